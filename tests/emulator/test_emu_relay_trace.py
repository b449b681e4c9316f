"""The relay's part of the SOE_Control handshake in mip-emulator's trace (--relay with --trace):
one small "relay" line for a read that shows offered entries and for each write to SOE_Control,
and a first line with the clock's origin (emulator/README.md, "Trace"; the live view draws them,
docs/view.md)."""
import json
import time

from mipcosim.trace import read_trace

from relay_support import BASE, Master, RelayServer, write_script

EVENTS = [(k / 1000, 0x0102, 100 + k, 0x0101, k) for k in range(1, 5)]  # 4 events at k ms


def lines(path):
    return read_trace(path)


def test_reads_and_acknowledgements_of_the_relay_are_traced_on_the_trace_clock(tmp_path):
    script = write_script(tmp_path / "events.txt", EVENTS)
    trace = tmp_path / "trace.jsonl"
    before = time.monotonic_ns()
    s = RelayServer(f"script={script}", ["--trace", str(trace)])
    m = Master(s.port)
    try:
        s.sleep_past(0.004, margin=0.1)
        assert m.count() == 4                     # the count alone: no line (nothing offered)
        entries, seq, blocks, _ = m.read()
        assert entries == 4 and len(blocks) == 3
        assert m.ack(seq, 3) == 0
        assert m.ack(seq, 1) != 0                 # a stale sequence number: refused, traced
        entries, seq2, blocks2, _ = m.read()
        assert entries == 1 and m.ack(seq2, 1) == 0
        m.read()                                  # nothing offered: no line
    finally:
        m.close()
        assert s.stop() == 0
    after = time.monotonic_ns()
    got = lines(trace)
    start, rest = got[0], got[1:]
    assert start["ev"] == "relay" and start["start"] is True and start["t"] == 0
    assert before <= start["mono_ns"] <= after    # the origin on CLOCK_MONOTONIC
    relay = [d for d in rest if d["ev"] == "relay"]
    assert [(d["fc"], d.get("offered"), d.get("w0"), d.get("exc"), d.get("acked"),
             d["entries"]) for d in relay] == [
        (3, 3, None, None, None, 4),
        (6, None, seq | 3 << 8, 0, 3, 1),
        (6, None, seq | 1 << 8, 3, 0, 1),
        (3, 1, None, None, None, 1),
        (6, None, seq2 | 1 << 8, 0, 1, 0)]
    assert relay[0]["ra"] == BASE and relay[0]["rq"] == 26
    assert relay[0]["soe"] == seq | 3 << 8 and relay[1]["wa"] == BASE + 1
    ts = [d["t"] for d in got]
    assert ts == sorted(ts) and [d["seq"] for d in got] == list(range(len(got)))
    assert all(len(json.dumps(d)) < 160 for d in relay)     # small lines


def test_without_a_trace_the_relay_answers_as_before(tmp_path):
    s = RelayServer(f"script={write_script(tmp_path / 'events.txt', EVENTS)}")
    m = Master(s.port)
    try:
        s.sleep_past(0.004, margin=0.1)
        entries, seq, blocks, _ = m.read()
        assert entries == 4 and [b["value"] for b in blocks] == [1, 2, 3]
        assert m.ack(seq, 3) == 0
    finally:
        m.close()
        assert s.stop() == 0
