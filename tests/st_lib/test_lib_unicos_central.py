"""The central of the chain: MIP_Receiver (xAckByCaller) hands each record to MIP_UnicosEvents,
which writes it to the WinCC OA stand-in; an outstation's MIP_Sender sends relay entries over
the emulated radio (tests/st_lib/stlib_sim.py). The radio acknowledgement of a record goes out
only after the driver took it: with the driver down, the outstation waits and nothing is lost;
when it comes back every entry arrives once, in order."""
import pytest

from mippeer.unicos import UnicosDriver
from stlib_sim import MS, Bench, ChunkSource, Fb, Port, Radio
from unicos_bench import Client, build, entry

T0 = 1767225600000
ENTRIES_PER_RECORD = 3


@pytest.fixture(scope="module")
def wd(tmp_path_factory):
    return tmp_path_factory.mktemp("unicos_central")


def test_the_radio_acknowledgement_waits_for_the_control_system(wd):
    plc_o, plc_c = build(wd), build(wd)          # one program: `snd` here, `rcv` + `cuni` there
    snd, rcv = Fb(plc_o, "snd"), Fb(plc_c, "rcv")
    uni = Fb(plc_c, "cuni")
    radio = Radio()
    entries = [entry(0x0100 + n % 16, 1 + n, 0x0101, n + 1, T0 + 10 * n) for n in range(12)]
    data = sum(entries, [])
    driver = UnicosDriver("A")
    parts = [ChunkSource(snd, data), Port(snd, radio.outstation), Port(rcv, radio.central)]
    bench = Bench([plc_o, plc_c], parts, radio)
    client = Client(bench, "A", driver, fb=uni, reg=lambda i: plc_c[f"MAIN.ua{i}"])
    bench.parts.append(client)
    snd["uChunkSize"] = 1 + 8 * ENTRIES_PER_RECORD      # counter + 3 entries a record
    snd["tTimeout"] = 300 * MS
    rcv["tTimeout"] = 300 * MS
    rcv["xAckByCaller"] = True
    rcv["xEnable"] = True
    uni["xEnable"] = True
    uni["tRetry"] = 100 * MS
    bench.step(2)

    client.down = True                                   # the control system is away
    snd["xExecute"] = True
    bench.step(400)
    assert driver.events == [] and uni["xError"]
    assert not snd["xDone"] and not snd["xError"]       # waiting for the acknowledgement
    assert rcv["udiRecords"] <= 1 and rcv.write_block(1)[0] == 0   # nothing acknowledged
    client.down = False
    assert bench.run_until(lambda: snd["xDone"] or snd["xError"], 5000)
    assert snd["xDone"]
    got = [(e["offset"], e["value"], e["ts_10ms"]) for e in driver.events]
    assert got == [(1 + n, (0x0100 + n % 16) << 16 | (n + 1), (T0 + 10 * n) // 10) for n in range(12)]
    assert driver.duplicates == 0 and uni["udiRecords"] == 12 // ENTRIES_PER_RECORD


def transfer_scans(wd, handover, delay_scans=0, n=24, per=3, poll_scans=5):
    """Scans until the outstation's transfer of n entries (per a record) is acknowledged:
    the central acknowledging on receipt, or after the driver's answer (delay_scans later)."""
    plc_o, plc_c = build(wd), build(wd)
    snd, rcv, uni = Fb(plc_o, "snd"), Fb(plc_c, "rcv"), Fb(plc_c, "cuni")
    radio = Radio(poll_scans=poll_scans)
    data = sum((entry(0x0100, 1 + k, 0x0101, k, T0 + 10 * k) for k in range(n)), [])
    driver = UnicosDriver("A")
    bench = Bench([plc_o, plc_c], [ChunkSource(snd, data), Port(snd, radio.outstation),
                                   Port(rcv, radio.central)], radio)
    bench.parts.append(Client(bench, "A", driver, fb=uni, reg=lambda i: plc_c[f"MAIN.ua{i}"],
                              delay_scans=delay_scans))
    snd["uChunkSize"] = 1 + 8 * per
    snd["tTimeout"] = rcv["tTimeout"] = 1000 * MS
    rcv["xAckByCaller"] = uni["xEnable"] = handover
    rcv["xEnable"] = True
    bench.step(2)
    snd["xExecute"] = True
    assert bench.run_until(lambda: snd["xDone"], 20000)
    assert len(driver.events) == (n if handover else 0)
    return bench.scans


# docs/chain.md's table: (radio poll every N scans, the driver's answer after D scans, the
# scans the 8 records take more than with the acknowledgement on receipt)
COST = [(5, 0, 0), (5, 2, 6), (5, 5, 40), (5, 10, 80), (10, 0, 0), (10, 2, 0), (10, 5, 0),
        (10, 10, 80)]


@pytest.mark.parametrize("poll,delay,extra", COST, ids=[f"poll{p}-answer{d}" for p, d, _ in COST])
def test_the_extra_round_trip_costs_only_when_the_driver_misses_the_next_poll(wd, poll, delay, extra):
    """The measured cost of acknowledging after the hand-over (docs/chain.md): 8 records of 3
    entries, 10 ms scans. Nothing while the answer comes before the station's next poll; the
    answer's time rounded up to poll cycles when it does not."""
    on_receipt = transfer_scans(wd, False, poll_scans=poll)
    assert transfer_scans(wd, True, delay_scans=delay, poll_scans=poll) - on_receipt == extra
