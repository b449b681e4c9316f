"""The CI matrix in co-simulation: the example programs (plc/) and the emulator core in one
process, lockstep virtual time. Every case asserts exact delivery (mipcosim.check)."""
import itertools
from pathlib import Path

import pytest

from mipcosim.check import check, summary
from mipcosim.sim import SEC, LoggerLink, Setup

if not (Path(__file__).resolve().parents[2] / "build" / "cosim" / "libmipcosim.so").is_file():
    pytest.fail("build/cosim/libmipcosim.so not built: run make first (these tests cannot run without it)", pytrace=False)

MATRIX = list(itertools.product(["dynamic", "static"], ["spontaneous", "polled"],
                                ["uni", "bidi"], [0.0, 0.1, 0.3],
                                ["none", "outstation", "central"]))
# the pipelined sender (uWindow 2 of MIP_Sender and MIP_Link, st_lib/PROTOCOL.md P27):
# dynamic, spontaneous, both layouts
MATRIX += list(itertools.product(["pipelined"], ["spontaneous"], ["uni", "bidi"], [0.0, 0.1, 0.3],
                                 ["none", "outstation", "central"]))


def run_case(workdir, mode, drive, layout, loss, restart, seed=7, records=24, per_transfer=7):
    st = Setup(static=mode == "static", polled=drive == "polled", bidi=layout == "bidi",
               window=2 if mode == "pipelined" else 1,
               loss=loss, seed=seed, records=records, per_transfer=per_transfer,
               # record n is logged at n * 50 ms: the read-out runs while the logger fills
               log_period_ms=50)
    with LoggerLink(st, workdir) as ch:
        if restart != "none":
            ch.run_for(SEC)          # mid read-out
            ch.restart(("out", 1) if restart == "outstation" else ("cen", 0))
        finished = ch.run_to_end(900 * SEC)
        reps = check(ch)
        return ch, finished, reps, summary(reps)


@pytest.mark.parametrize("mode,drive,layout,loss,restart", MATRIX,
                         ids=["-".join([m, d, l, f"loss{int(p * 100)}", r])
                              for m, d, l, p, r in MATRIX])
def test_chain_matrix_exact_delivery(chain_workdir, mode, drive, layout, loss, restart):
    ch, finished, reps, tot = run_case(chain_workdir, mode, drive, layout, loss, restart)
    problems = [p for r in reps for p in r.problems]
    assert finished, f"not all records read out after {ch.now / SEC:.0f} s: {tot} {problems}"
    assert problems == []
    assert tot["lost"] == 0
    for r in reps:
        # all 24 logger records are in complete transfers at the receiver, and a record
        # arrived twice only in a transfer whose failure the sender reported
        assert r.records >= 24, (r.name, r.records)
        if r.delivered_after_failure == 0:
            assert r.duplicated_records == 0 and r.records == 24, r
    if restart == "none":
        streams = 2 if layout == "bidi" else 1
        assert tot["duplicated"] == 0 and tot["failed_reported"] == 0
        assert tot["cut_by_restart"] == 0 and tot["receiver_reports"] == 0
        assert tot["records"] == 24 * streams and tot["transfers"] == 4 * streams


def test_chain_pipelined_soak_with_restarts(capsys):
    """Issue 15: the pipelined sender under 30 % loss with a cold restart of one side every
    30 s (make soak SOAK_ARGS="--window 2" runs 10^5 records): nothing lost, nothing twice;
    the transfers a restart cut are reported."""
    from mipcosim import cli
    rc = cli.main(["soak", "--window", "2", "--records", "3000", "--per-transfer", "100",
                   "--restart-every", "30"])
    out = capsys.readouterr().out
    assert rc == 0, out
    result = out.strip().splitlines()[-1]
    assert result.startswith("result: ok records=3000 lost=0 duplicated=0 "), result
    assert "restarts=0 " not in result, result


def test_chain_same_seed_same_run(chain_workdir, tmp_path):
    """Lockstep virtual time: a seed gives the same emulator trace bytes and the same events."""
    runs = []
    for k in range(2):
        st = Setup(loss=0.2, seed=11, records=12, per_transfer=5, bidi=True)
        trace = tmp_path / f"trace{k}.jsonl"
        with LoggerLink(st, chain_workdir, trace=trace) as ch:
            ch.run_to_end(300 * SEC)
            events = [(e.t, e.tap, e.words) for e in ch.events]
            stats = ch.radio_stats()
        runs.append((trace.read_bytes(), events, stats))
    assert runs[0][0] == runs[1][0] and len(runs[0][0]) > 10_000
    assert runs[0][1] == runs[1][1]
    assert runs[0][2] == runs[1][2]


@pytest.mark.parametrize("restart", ["none", "central"])
def test_chain_inproc_transport_same_trace_as_modbus_tcp(chain_workdir, tmp_path, restart):
    """The kernel's in-process transport (request ADU handed to the emulator core) and libmodbus
    over a real TCP connection on 127.0.0.1 (and over a socketpair) give the same emulator
    trace, byte for byte (every Modbus request with its transaction id, every radio telegram),
    and the same delivered records."""
    runs = {}
    for transport in ("tcp", "socketpair", "inproc"):
        st = Setup(loss=0.3, seed=23, records=14, per_transfer=5, bidi=True, stations=2,
                   transport=transport)
        trace = tmp_path / f"trace-{transport}.jsonl"
        with LoggerLink(st, chain_workdir, trace=trace) as ch:
            if restart == "central":
                ch.run_for(SEC)
                ch.restart(("cen", 0))
            assert ch.run_to_end(600 * SEC)
            events = [(e.t, e.tap, e.words) for e in ch.events]
            runs[transport] = (trace.read_bytes(), events, ch.radio_stats())
    tcp, ip = runs["tcp"], runs["inproc"]
    assert b'"ev":"modbus"' in tcp[0] and len(tcp[0]) > 10_000
    assert tcp[0] == ip[0]
    assert tcp[1] == ip[1] and len(tcp[1]) > 0
    assert tcp[2] == ip[2]
    assert runs["socketpair"] == tcp


def test_chain_scan_tick_is_a_parameter(chain_workdir):
    """50 ms scans: the programs are built with that task interval (their timers follow the
    kernel's clock) and the transfer under loss is still exact."""
    st = Setup(loss=0.1, seed=3, records=12, per_transfer=5, tick_ms=50, log_period_ms=100)
    with LoggerLink(st, chain_workdir) as ch:
        assert all(p.tick_ns == 50_000_000 for p in ch.plcs.values())
        assert ch.run_to_end(600 * SEC)
        scans = ch.radio_stats()["scans"]
        reps = check(ch)
        tot = summary(reps)
        # two PLCs, one scan each per 50 ms of virtual time
        assert abs(scans - 2 * ch.now // 50_000_000) <= 2
    assert [p for r in reps for p in r.problems] == []
    assert tot["records"] == 12 and tot["lost"] == 0 and tot["duplicated"] == 0


def test_chain_transport_name_is_checked(chain_workdir):
    with pytest.raises(Exception, match="transport 'udp': use inproc, socketpair or tcp"):
        LoggerLink(Setup(transport="udp"), chain_workdir)


def test_chain_other_seed_other_losses(chain_workdir):
    stats = []
    for seed in (1, 2):
        with LoggerLink(Setup(loss=0.3, seed=seed, records=6), chain_workdir) as ch:
            ch.run_to_end(300 * SEC)
            stats.append(ch.radio_stats())
            assert check(ch)[0].problems == []
    assert stats[0]["lost_up"] + stats[0]["lost_down"] > 0
    assert stats[0] != stats[1]


def test_chain_four_stations_one_central(chain_workdir):
    st = Setup(stations=4, loss=0.1, seed=5, records=10, per_transfer=4, bidi=True)
    with LoggerLink(st, chain_workdir) as ch:
        assert ch.run_to_end(600 * SEC)
        reps = check(ch)
    assert [p for r in reps for p in r.problems] == []
    assert len(reps) == 8 and all(r.records == 10 and r.transfers == 3 for r in reps)


def test_chain_checker_catches_a_corrupted_record(chain_workdir):
    """The check is not blind: alter one delivered register and it fails."""
    with LoggerLink(Setup(records=5), chain_workdir) as ch:
        ch.run_to_end(60 * SEC)
        ev = next(e for e in ch.events if e.tap == 1 and e.words[0] & 1)
        ev.words[4 + 5] ^= 1
        problems = [p for r in check(ch) for p in r.problems]
    assert any("differs from the logger's" in p for p in problems)


def test_chain_checker_catches_a_lost_transfer(chain_workdir):
    with LoggerLink(Setup(records=10, per_transfer=3), chain_workdir) as ch:
        ch.run_to_end(60 * SEC)
        # drop the receiver's events of the second transfer
        rec = [e for e in ch.events if e.tap == 1]
        second = [e for e in rec if e.words[1] in (1, 2, 0xFFFF)][3:6]
        for e in second:
            ch.events.remove(e)
        problems = [p for r in check(ch) for p in r.problems]
    assert any("LOST" in p for p in problems)


@pytest.mark.parametrize("radio,burst", [("realistic", 0.0), ("fast", 8.0)],
                         ids=["realistic-timing", "burst-losses"])
def test_chain_realistic_timing_and_burst_losses(chain_workdir, radio, burst):
    """9600 bit/s with 20 ms gaps (tTimeout 3 s), and Gilbert-Elliott bursts of 8 telegrams
    at 30 % loss: still exact delivery, both directions."""
    from mipcosim.sim import Radio
    st = Setup(loss=0.3, burst=burst, seed=4, records=15, per_transfer=6, bidi=True,
               radio=Radio.realistic() if radio == "realistic" else Radio(),
               timeout_ms=3000 if radio == "realistic" else 300)
    with LoggerLink(st, chain_workdir) as ch:
        assert ch.run_to_end(3600 * SEC)
        reps = check(ch)
        stats = ch.radio_stats()
    assert [p for r in reps for p in r.problems] == []
    assert all(r.records == 15 and r.duplicated_records == 0 for r in reps)
    assert stats["lost_up"] + stats["lost_down"] > 0


@pytest.mark.skipif(not __import__("plcharness.build", fromlist=["x"]).matiec_available(),
                    reason="iec2c not on PATH (set PATH and MATIEC_LIB to run the chain on matiec)")
@pytest.mark.parametrize("layout,mode,restart", [("uni", "dynamic", "none"),
                                                 ("bidi", "static", "outstation"),
                                                 ("bidi", "dynamic", "central")])
def test_chain_programs_compiled_by_matiec(chain_workdir, layout, mode, restart):
    """The same chain with the programs compiled by matiec instead of stc."""
    st = Setup(static=mode == "static", polled=True, bidi=layout == "bidi", loss=0.3, seed=7,
               records=24, per_transfer=7, log_period_ms=50, compiler="matiec")
    with LoggerLink(st, chain_workdir) as ch:
        if restart != "none":
            ch.run_for(SEC)
            ch.restart(("out", 1) if restart == "outstation" else ("cen", 0))
        assert ch.run_to_end(900 * SEC)
        reps = check(ch)
    assert [p for r in reps for p in r.problems] == []
    assert all(r.records == 24 and r.lost == 0 for r in reps)
