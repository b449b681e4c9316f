"""MIP_Link with uWindow = 2: the pipelined sender (st_lib/PROTOCOL.md P27) in the
bidirectional layout (note 2.2), where every write of a side carries its newest record and its
acknowledgement of the other stream, and an acknowledgement counts only once the own modem
confirmed the block it answers (P9). Checked in the model first (configurations win2/bidi/...,
win2/bidi-noC3/...)."""
import random
from pathlib import Path

import pytest

from stlib_sim import FFFF, Bi, pattern

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


def test_both_streams_pipeline_and_deliver_exactly(wd):
    up, down = pattern(20 * 121, seed=950), pattern(20 * 121, seed=951)
    b1 = Bi(wd, up, down)
    r1, scans1 = run(b1, 1)
    b2 = Bi(wd, up, down)
    r2, scans2 = run(b2, 2)
    assert r1 == r2 == ["done", "done"]
    for b in (b1, b2):
        assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
        assert numbers(b.sink_c) == numbers(b.sink_o) == list(range(1, 20)) + [FFFF]
    assert pipelined(b1.radio, "up") == [] and pipelined(b1.radio, "down") == []
    # from record 3 on (record 2 waits for the acknowledgement of record 1) records go up
    # before the acknowledgement of the one before them, in both directions
    assert len(pipelined(b2.radio, "up")) >= 10, pipelined(b2.radio, "up")
    assert len(pipelined(b2.radio, "down")) >= 10, pipelined(b2.radio, "down")
    assert min(pipelined(b2.radio, "up") + pipelined(b2.radio, "down")) >= 3
    assert FFFF not in pipelined(b2.radio, "up") + pipelined(b2.radio, "down")
    assert scans2 < 0.8 * scans1, (scans1, scans2)
    for fb in (b2.lo, b2.lc):
        assert fb["udiRecordsSent"] == 20 and fb["udiRetransmissions"] == 0


def test_one_busy_stream_pipelines_every_record_from_3(wd):
    """With the other stream idle the link's writes are the records alone: as in the
    unidirectional layout every record from 3 to the one before 16#FFFF goes up before the
    acknowledgement of the one before it, in about 3/5 of the polls of window 1 (both streams
    busy gain less: every acknowledgement write of the other stream sends the newest record
    again, and the next one waits for that copy's confirmation; PROTOCOL.md section 12)."""
    up = pattern(20 * 121, seed=952)
    polls = {}
    for w in (1, 2):
        b = Bi(wd, up, [])
        b.lo["uWindow"] = w
        b.lo["xExecute"] = True
        assert b.bench.run_until(lambda: b.lo["xSendDone"], 20000)
        assert b.sink_c.transfers == [up]
        polls[w] = b.radio.stats()["polls"]
        if w == 2:
            assert pipelined(b.radio, "up") == list(range(3, 20))
    assert polls[2] < 0.65 * polls[1], polls


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


def test_goes_back_when_a_side_reads_too_slowly(wd):
    """The central reads every 12 scans, the radio polls every 5 (configuration rule C3
    broken): a pipelined record overwrites the unread one before it; the central ignores the
    unexpected number, the outstation's repeat goes back and closes the window. Nothing lost,
    nothing twice, in either stream."""
    up, down = pattern(16 * 121, seed=980), pattern(6 * 121, seed=981)
    b = Bi(wd, up, down)
    b.port_c.read_every = 12
    res, _ = run(b, 2, limit=60000)
    assert res == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert numbers(b.sink_c) == list(range(1, 16)) + [FFFF]
    assert b.lc["udiUnexpected"] >= 1
    assert b.lo["udiRetransmissions"] >= 1
    assert pipelined(b.radio, "up")


def test_polled_link_stays_stop_and_wait(wd):
    up, down = pattern(6 * 121, seed=990), pattern(6 * 121, seed=991)
    b = Bi(wd, up, down, polled=True)
    res, _ = run(b, 2)
    assert res == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert pipelined(b.radio, "up") == [] and pipelined(b.radio, "down") == []


def test_link_window_is_latched_at_execute(wd):
    """P26: uWindow is the sending side's, sampled at the rising edge of xExecute."""
    up = pattern(8 * 121, seed=995)
    b = Bi(wd, up, [])
    b.lo["uWindow"] = 1
    b.lo["xExecute"] = True
    b.bench.step(5)
    b.lo["uWindow"] = 2
    assert b.bench.run_until(lambda: b.lo["xSendDone"], 20000)
    assert pipelined(b.radio, "up") == []
    b.lo["xExecute"] = False
    b.bench.step(2)
    first = len(b.radio.log)
    b.lo["xExecute"] = True
    assert b.bench.run_until(lambda: b.lo["xSendDone"], 20000)
    assert b.sink_c.transfers == [up, up]
    assert pipelined(b.radio, "up", first)
