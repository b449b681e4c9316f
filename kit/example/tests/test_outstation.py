"""The outstation program's tests, through the test kit's pytest plugin (fixture mip_network).

The central is the note-following peer at the MDP-810; the outstation PLC runs st/Outstation.st
with its plcrt config, attached to station 1."""
from pathlib import Path

from mipkit import assert_records

HERE = Path(__file__).resolve().parent.parent
SOURCES = [HERE / "st" / "FieldLogger.st", HERE / "st" / "Outstation.st"]
CONFIG = HERE / "plcrt" / "outstation.conf"


def expected(n):
    """What FieldLogger puts into record n."""
    return [n % 65536, n // 65536] + [(n * k) % 65536 for k in range(3, 9)]


def start(net, mip_st_lib, records):
    out = net.plc("outstation", mip_st_lib + SOURCES, CONFIG, at=1)
    central = net.peer("central", at="mdp")
    out["%MW1"], out["%MW2"], out["%MW0"] = records % 65536, records // 65536, 1
    return out, central


def logged(out):
    return out["%MW10"] + 65536 * out["%MW11"]


def test_readout_over_lossy_radio_with_warm_restart(mip_network, mip_st_lib):
    net = mip_network(radio="realistic", loss_down=0.1, loss_up=0.1, seed=3)
    out, central = start(net, mip_st_lib, 200)
    net.run_for(8)
    out.restart("warm")                     # plcrt stopped with SIGTERM: a snapshot at the stop
    errors = []
    done = net.run_until(lambda: errors.append(out["%MW14"]) or
                         len(central.records) == logged(out) == 200, within_s=600)
    assert done, f"not complete: logged {logged(out)}, delivered {len(central.records)}"
    assert not any(errors), "MIP_Sender reported xError"
    assert assert_records(central.records, expected) == 200


def test_kill9_and_lost_answers(mip_network, mip_st_lib):
    net = mip_network(radio="fast", seed=5)
    out, central = start(net, mip_st_lib, 150)
    net.lose(1, "up", record=5, times=3)    # record 5 lost three times on the way up
    net.run_for(3)
    out.restart("kill9")                    # kill -9: back to the last periodic snapshot
    assert net.run_until(lambda: len(central.records) == logged(out) == 150, within_s=300), \
        f"central accepted {len(central.records)} records, the outstation logged {logged(out)}, want 150"
    assert [x[3] for x in net.lost] == [5, 5, 5]
    assert not out["FieldStation.snd.xError"], \
        "MIP_Sender reported xError (its eErrorId: the report's first lines)"
    assert_records(central.records, expected)
