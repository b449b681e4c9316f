"""MIP_Link with uWindow = 2: the bidirectional layout (note 2.2) runs stop and wait.

The pipelined sender (st_lib/PROTOCOL.md P27) is withdrawn in this layout: the model found a
record lost after a restart of the sending PLC (configurations win2/bidi/..., GAP): a stale
acknowledgement of record 1 counts (the residual of P9), and the peer's writes, which carry
its acknowledgement with every record of the other stream, can still carry the number of the
old session when it equals the pipelined record. MIP_Link accepts uWindow = 2 and runs
window 1; these tests show that it never pipelines and still delivers exactly."""
import random
from pathlib import Path

import pytest

from stlib_sim import ERR, FFFF, Bi, pattern

# register of each stream in a block, and which side writes its records
STREAMS = {"up": (0, "O"), "down": (1, "C")}


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_window_bidi")


def pipelined(radio, stream, start=0):
    """Record numbers of `stream` that went up no later than the poll that carried the
    acknowledgement of the record before them (stop and wait sends a record at the earliest
    in the poll after)."""
    reg, writer = STREAMS[stream]
    acked_in = {}
    for t in radio.log[start:]:
        if t.src != writer and len(t.block) > reg:
            acked_in.setdefault(t.block[reg], t.poll)
    out = set()
    for t in radio.log[start:]:
        if t.src == writer and len(t.block) > reg:
            n = t.block[reg]
            if n not in (0, 1, FFFF) and (n - 1 not in acked_in or acked_in[n - 1] >= t.poll):
                out.add(n)
    return sorted(out)


def run(bi, window, limit=20000):
    for fb in (bi.lo, bi.lc):
        fb["uWindow"] = window
    bi.bench.step(3)
    start = bi.bench.scans
    res = bi.send_both(limit)
    return res, bi.bench.scans - start


def numbers(sink):
    return [n for n, _ in sink.records]


def test_window_2_runs_stop_and_wait_in_both_streams(wd):
    up, down = pattern(20 * 121, seed=950), pattern(20 * 121, seed=951)
    b1 = Bi(wd, up, down)
    r1, scans1 = run(b1, 1)
    b2 = Bi(wd, up, down)
    r2, scans2 = run(b2, 2)
    assert r1 == r2 == ["done", "done"]
    for b in (b1, b2):
        assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
        assert numbers(b.sink_c) == numbers(b.sink_o) == list(range(1, 20)) + [FFFF]
        assert pipelined(b.radio, "up") == [] and pipelined(b.radio, "down") == []
        for fb in (b.lo, b.lc):
            assert fb["udiRecordsSent"] == 20 and fb["udiRetransmissions"] == 0
    # the same run, scan for scan: uWindow = 2 changes nothing in this layout
    assert scans2 == scans1, (scans1, scans2)


def test_one_busy_stream_does_not_pipeline(wd):
    up = pattern(20 * 121, seed=952)
    b = Bi(wd, up, [])
    b.lo["uWindow"] = 2
    b.lo["xExecute"] = True
    assert b.bench.run_until(lambda: b.lo["xSendDone"], 20000)
    assert b.sink_c.transfers == [up]
    assert pipelined(b.radio, "up") == []


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_exact_under_loss_and_duplicates(wd, seed):
    up, down = pattern(12 * 121 + 5, seed=960 + seed), pattern(9 * 121, seed=970 + seed)
    rnd = random.Random(seed)
    b = Bi(wd, up, down, fate=lambda src, block: rnd.choices(["ok", "lost", "dup"], [6, 2, 2])[0])
    res, _ = run(b, 2, limit=60000)
    assert res == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert numbers(b.sink_c) == list(range(1, 13)) + [FFFF]
    assert numbers(b.sink_o) == list(range(1, 9)) + [FFFF]


def test_exact_when_a_side_reads_too_slowly(wd):
    """The central reads every 12 scans, the radio polls every 5 (configuration rule C3
    broken): stop and wait still delivers everything once, in either stream."""
    up, down = pattern(16 * 121, seed=980), pattern(6 * 121, seed=981)
    b = Bi(wd, up, down)
    b.port_c.read_every = 12
    res, _ = run(b, 2, limit=60000)
    assert res == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert numbers(b.sink_c) == list(range(1, 16)) + [FFFF]
    assert pipelined(b.radio, "up") == []


def test_polled_link_stays_stop_and_wait(wd):
    up, down = pattern(6 * 121, seed=990), pattern(6 * 121, seed=991)
    b = Bi(wd, up, down, polled=True)
    res, _ = run(b, 2)
    assert res == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert pipelined(b.radio, "up") == [] and pipelined(b.radio, "down") == []


def test_link_without_confirmation_still_fails_after_max_retries(wd):
    """P3 (bidirectional): while the own modem has not confirmed the record, the link writes
    it no more (the modem repeats it at every poll itself), but each expired tTimeout still
    counts for uMaxRetries (P14): a radio that delivers nothing ends in MIP_ERR_NO_ACK, not in
    a silent wait."""
    up = pattern(3 * 121, seed=996)
    b = Bi(wd, up, [], fate=lambda src, block: "lost" if src == "O" else "ok")
    b.lo["uMaxRetries"] = 2
    b.lo["xExecute"] = True
    assert b.bench.run_until(lambda: b.lo["xSendError"], 20000)
    assert b.lo["eSendErrorId"] == ERR["MIP_ERR_NO_ACK"]
    assert b.lo["udiRetransmissions"] == 0      # the modem repeated it, the link did not
    assert b.sink_c.transfers == []
