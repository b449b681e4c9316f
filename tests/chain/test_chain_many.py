"""The central of a large network (plc/central_many.st): ONE program with a receiver per station
behind one shared Modbus client (unit id from the image, plcrt `unit_id = %QWn`), up to the
247 stations one MDP-810 serves, in the co-simulation kernel (mipcosim.sim.Network)."""
import subprocess
import sys
from pathlib import Path

import pytest

from mipcosim import programs as L
from mipcosim.sim import SEC, CosimError, Network, Radio

REPO = Path(__file__).resolve().parents[2]


def run_to_end(net, limit_s, settle_s=3):
    while net.now < limit_s * SEC:
        net.run_for(SEC)
        if net.finished():
            net.run_for(settle_s * SEC)
            return True
    return False


def test_chain_many_one_central_reads_out_every_station_exactly(chain_workdir):
    with Network(6, chain_workdir / "many6", records=7, per_transfer=3, payload=20,
                 tick_ms=10) as net:
        assert run_to_end(net, 600), [net.station(s) for s in range(1, 7)]
        assert net.check() == []
        assert net.central(L.M_STATIONS) == 6
        # 3 transfers per station: 1, 2, FFFF | 1, 2, FFFF | 1, FFFF (the logger ends a
        # transfer that is not full with an empty last record, which the receiver does not
        # deliver): 7 records delivered, one client
        assert net.central(L.M_TRANSFERS) == 6 * 3
        assert net.central(L.M_REC_LO) == 6 * 7
        assert net.central(L.M_FAILED) == 0
        assert net.central(L.M_READS) > 6 and net.central(L.M_WRITES) >= 6 * 7
        assert net.central(L.M_READ_ERRS) == 0 and net.central(L.M_WRITE_ERRS) == 0


@pytest.mark.parametrize("seed", [2, 7])
def test_chain_many_exact_under_loss(chain_workdir, seed):
    with Network(5, chain_workdir / f"many-loss{seed}", records=12, per_transfer=5, loss=0.3,
                 seed=seed, tick_ms=10, radio=Radio()) as net:
        assert run_to_end(net, 900)
        assert net.check() == []
        assert net.radio_stats()["lost_up"] + net.radio_stats()["lost_down"] > 0


def test_chain_many_full_network_of_247_stations(chain_workdir):
    """The largest MIP network: 247 outstations and one central program, every station's two
    records delivered once (a fast radio: the point here is the scale, not timing; 100 ms scans
    as in the bench line cosim_scale, which so finds the program built)."""
    with Network(247, chain_workdir / "many247", records=2, payload=8, tick_ms=100,
                 radio=Radio()) as net:
        assert run_to_end(net, 900, settle_s=1)
        assert net.check() == []
        assert net.central(L.M_TRANSFERS) == 247
        # every station was read in turn: at least one full round
        assert net.central(L.M_ROUNDS) >= 1


def test_chain_many_a_check_that_would_see_loss(chain_workdir):
    """check() is not blind: a station whose data did not all arrive is named."""
    with Network(2, chain_workdir / "many-cut", records=40, payload=30, tick_ms=10) as net:
        net.run_for(2 * SEC)            # stopped long before the 9600 bit/s radio is through
        problems = net.check()
        assert any(p.startswith("station 1:") for p in problems)
        assert any(p.startswith("station 2:") for p in problems)


def test_chain_many_station_count_is_checked(chain_workdir):
    with pytest.raises(CosimError, match=r"stations 248: one MDP-810 serves unit ids 1\.\.247"):
        Network(248, chain_workdir / "many-bad")


def test_chain_many_generator_refuses_a_bad_count():
    p = subprocess.run([sys.executable, str(REPO / "plc" / "gen_programs.py"), "--many-stations",
                        "0", "-o", "/nonexistent"], capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "--many-stations 0" in p.stderr


def test_a_closed_kernel_says_so_instead_of_crashing(chain_workdir):
    """After close() (the end of a `with` block) the time it ended at stays readable, and any
    further use of the kernel is one clear error, not a use of freed memory (it segfaulted)."""
    with Network(2, chain_workdir / "closed", records=2, per_transfer=2) as net:
        net.run_for(2 * SEC)
        end = net.now
    assert net.now == end == 2 * SEC
    with pytest.raises(CosimError, match="the co-simulation is closed"):
        net.run_for(SEC)
    with pytest.raises(CosimError, match="the co-simulation is closed"):
        net.radio_stats()
