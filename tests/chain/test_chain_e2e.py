"""The whole chain of issue 35 in the co-simulation (cosim/mipcosim/chain.py): relay (C core) ->
outstation PLC (plc/outstation_soe.st) -> radio -> central PLC (plc/central_soe.st) -> the SCADA
stand-in, one virtual time. Every relay event must reach the SCADA once, in order, with its
time stamp and value, and the relay's recorder must be empty at the end."""
from pathlib import Path

import pytest

from mipcosim.chain import (ChainSetup, SoeChain, SoeParams, check_chain, expected, program_sources,
                            script)
from mipcosim.sim import MS, SEC
from plcharness.build import build_program, matiec_available

REPO = Path(__file__).resolve().parents[2]


def run_chain(workdir, events, loss, faults=(), retain=True, ack_on_receipt=False, seed=1,
              limit_s=120, scada_ms=50, handover="pull"):
    """faults: (virtual s, what) with what ("out" | "cen", kind), "scada" (a 2 s outage of the
    SCADA, or of the active driver with handover push) or "failover" (push)."""
    st = ChainSetup(events=events, loss=loss, seed=seed, scada_period_ms=scada_ms, handover=handover,
                    params=SoeParams(retain=retain, ack_on_receipt=ack_on_receipt,
                                     redundant=handover == "push"))
    with SoeChain(st, workdir) as ch:
        for at_s, what in faults:
            ch.run_until(max(ch.now, int(at_s * SEC)))
            if what == "scada" and handover == "push":
                ch.driver_outage(2 * SEC)
            elif what == "failover":
                ch.failover()
            elif what == "relay":
                ch.restart_relay()
            elif what == "scada":
                ch.scada_outage(2 * SEC)
            else:
                ch.restart(*what, down_ns=700 * MS)
        finished = ch.run_to_end(limit_s * SEC)
        ch.final_radio = ch.radio_stats()       # (the kernel is gone after the with)
        return finished, check_chain(ch), ch


def test_chain_exact_at_30_percent_loss_with_warm_restarts_of_both_plcs(chain_workdir):
    """300 events; the outstation killed (its last snapshot) while reading the relay, the central
    killed while handing over, the SCADA away for 2 s: each event once, in order, unchanged."""
    events = script(300)
    finished, rep, ch = run_chain(chain_workdir, events, 0.3,
                                  [(4.0, ("out", "warm")), (7.3, ("cen", "warm")), (10.1, "scada"),
                                   (12.2, ("cen", "graceful"))])
    assert finished and rep.problems == [], rep.problems
    assert (rep.taken, rep.lost, rep.duplicated, rep.relay_left) == (300, 0, 0, 0)
    got = [(r["type_bit"], r["address"], r["cause_type"], r["value"], r["ts_ms"]) for r in ch.rows]
    assert got == expected(events)          # the relay's own time stamps, unchanged
    assert [kind for _, _, kind in ch.restarts] == ["warm", "warm", "graceful"]
    assert ch.final_radio["lost_up"] > 0 and ch.scada_failures > 0   # the faults did happen


def test_push_chain_exact_with_a_fail_over_a_driver_outage_and_warm_restarts(chain_workdir):
    """The push way: the central writes UNICOS event frames to a redundant pair of drivers;
    fail-over to B, B down for 2 s, both PLCs killed: each driver has every event once, in
    order, with its time stamp (10 ms) and value."""
    events = script(300)
    finished, rep, ch = run_chain(chain_workdir, events, 0.3,
                                  [(3.0, "failover"), (5.0, "scada"), (8.2, ("cen", "warm")),
                                   (10.5, ("out", "warm")), (12.0, "failover")], handover="push")
    assert finished and rep.problems == [], rep.problems
    assert rep.lost == rep.duplicated == 0 and rep.taken == 2 * 300      # both drivers, once each
    for d in "ab":
        got = [(e["offset"], e["value"], e["ts_10ms"]) for e in ch.drivers[d].events]
        assert got == [(w[1], w[0] << 16 | w[3], (ts // 10)) for (_, w), (*_, ts) in
                       zip(events, expected(events))], d
        assert ch.drivers[d].duplicates == 0


def test_a_relay_restart_between_two_bursts_loses_and_repeats_nothing(chain_workdir):
    """The relay restarts (mipcosim_relay_restart: recorder empty, sequence number 0) after the
    outstation took its entries and before the next ones: the reader sees 0 (a relay that
    started, docs/chain.md "How a read is judged") and takes the new relay's numbers from 1;
    every event arrives once, in order."""
    events = script(50) + [(t + 6.0, w) for t, w in script(50, seed=2)]   # 0.5..2.95, 6.5..8.95 s
    finished, rep, ch = run_chain(chain_workdir, events, 0.3, [(5.5, "relay")])
    assert finished and rep.problems == [] and rep.lost == rep.duplicated == 0, rep.problems
    assert rep.lost_at_relay == 0 and [w for _, w, _ in ch.restarts] == ["relay"]


def test_a_relay_restart_with_events_right_after_it(chain_workdir):
    """The relay restarts while events keep coming, its first offer (number 1) before the
    reader saw its 0: the reader takes it as a restarted relay (MIP_SoeReader
    udiRelayRestarts) and the chain goes on; nothing lost but what the relay lost itself,
    nothing twice."""
    finished, rep, _ = run_chain(chain_workdir, script(400), 0.3, [(3.02, "relay")], limit_s=60)
    assert finished and rep.lost == 0 and rep.duplicated == 0 and rep.problems == [], rep.problems


def test_a_cold_central_loses_nothing_and_its_duplicates_are_exact_copies(chain_workdir):
    """Nothing retained at the central: records handed over but not yet acknowledged over the
    radio come again; the SCADA sees them twice with the same time stamp and value, none lost."""
    finished, rep, _ = run_chain(chain_workdir, script(200), 0.3,
                                 [(3.0, ("cen", "cold")), (6.0, ("cen", "cold"))])
    assert finished and rep.lost == 0 and rep.changed == 0 and rep.relay_left == 0, rep.problems
    assert rep.taken == 200 + rep.duplicated
    assert rep.duplicated == rep.restart_duplicates and rep.problems == []   # each around a restart


def test_acknowledging_on_receipt_loses_entries_over_a_central_restart(chain_workdir):
    """The must-fail variant: a central that acknowledges a record over the radio as soon as its
    entries are queued for the SCADA (PLC_SoeHandOver.xWaitScada FALSE) and restarts cold loses
    what the SCADA (polling every second here) had not taken yet; the check says so. The same
    run acknowledging after the hand-over loses nothing."""
    finished, rep, _ = run_chain(chain_workdir, script(200, every_s=0.01), 0.0,
                                 [(3.0, ("cen", "cold")), (6.0, ("cen", "cold"))],
                                 retain=False, ack_on_receipt=True, limit_s=60, scada_ms=1000)
    assert rep.lost > 0 and any("never reached the control system" in p for p in rep.problems)
    finished, rep, _ = run_chain(chain_workdir, script(200, every_s=0.01), 0.0,
                                 [(3.0, ("cen", "cold")), (6.0, ("cen", "cold"))],
                                 retain=False, limit_s=200, scada_ms=1000)
    assert finished and rep.lost == 0, rep.problems


def test_mip_cosim_run_chain_prints_one_result_line(capsys):
    from mipcosim.cli import main
    rc = main(["run", "--chain", "--events", "45", "--loss", "0.2"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert out.strip().splitlines()[-1].startswith("result: ok events=45 lost 0 duplicated 0 ")


def test_mip_cosim_chain_bad_option_is_one_line(capsys):
    from mipcosim.cli import main
    with pytest.raises(SystemExit) as e:
        main(["run", "--chain", "--per-record", "16"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--per-record must be in 1..15" in err and "Traceback" not in err


@pytest.mark.slow
@pytest.mark.parametrize("seed", [2, 3, 4])
def test_chain_random_faults_many_seeds(tmp_path, seed):
    """Faults at random times, three seeds: 1500 events at 30 % loss."""
    import random
    rnd = random.Random(seed)
    faults, t = [], 2.0
    for k in range(12):
        t += rnd.uniform(1.0, 5.0)
        faults.append((t, "scada" if k % 3 == 2 else
                       (("out", "cen")[k % 3], "graceful" if rnd.random() < 0.3 else "warm")))
    finished, rep, _ = run_chain(tmp_path, script(1500, seed=seed), 0.3, faults, seed=seed,
                                 limit_s=400)
    assert finished and rep.problems == [], rep.problems


# slow: three whole-program matiec builds (~16 s each); the quick tier's matiec check of the
# library is tests/st_lib/test_lib_compile.py
@pytest.mark.slow
@pytest.mark.skipif(not matiec_available(),
                    reason="iec2c not on PATH (set PATH and MATIEC_LIB to compile with matiec)")
@pytest.mark.parametrize("role,handover", [("out", "pull"), ("cen", "pull"), ("cen", "push")])
def test_chain_programs_compile_with_matiec(tmp_path, role, handover):
    res = build_program(program_sources(role, handover), tmp_path / "out", compiler="matiec")
    assert res.executable.is_file()


@pytest.mark.slow
@pytest.mark.parametrize("cold", [False, True], ids=["warm", "central-cold"])
def test_chain_soak_20000_events(capsys, cold):
    """The soak's shape, shorter (20,000 events, a fault every 10 s): warm restarts lose and
    repeat nothing; a cold central loses nothing and each duplicate lies around its restart."""
    from mipcosim.cli import main
    rc = main(["soak", "--chain", "--events", "20000", "--restart-every", "10"]
              + (["--cold"] if cold else []))
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert rc == 0 and last.startswith("result: ok events=20000 lost 0 "), last
    if not cold:
        assert " duplicated 0 failed 0 " in last, last


@pytest.mark.slow
def test_push_chain_soak_20000_events(capsys):
    """The push way: lost 0; a duplicate only around a kill -9 of the central (docs/chain.md)."""
    from mipcosim.cli import main
    rc = main(["soak", "--chain", "--handover", "push", "--events", "20000", "--restart-every", "10"])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert rc == 0 and last.startswith("result: ok events=20000 lost 0 "), last
