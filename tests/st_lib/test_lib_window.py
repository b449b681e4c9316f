"""MIP_Sender with uWindow = 2: the pipelined sender of st_lib/PROTOCOL.md P27 (issue 15),
against our receiver and a note central, with loss, a receiving PLC slower than the radio, and
the modes where the window does not apply. The rules were checked in the model first
(model/, configurations win2/...)."""
import random
from pathlib import Path

import pytest

from stlib_sim import FFFF, Uni, enum_values, pattern

WIN = enum_values("E_MIP_WindowState")
from test_lib_interop import uni_vs_note_central


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_window")


def records_up(radio):
    """Record numbers of the outstation's telegrams, in order (repeats included)."""
    return [t.block[0] for t in radio.log if t.src == "O"]


def pipelined(radio, start=0):
    """Records that went up no later than the poll that brought down the acknowledgement of
    the record before them: with stop and wait a record goes up at the earliest in the poll
    after (the outstation reads the acknowledgement between polls). t.poll: the radio poll a
    telegram went in (a poll: the central's telegram, then the outstation's)."""
    acked_in = {}
    for t in radio.log[start:]:
        if t.src == "C":
            acked_in.setdefault(t.block[0], t.poll)
    out = []
    for t in radio.log[start:]:
        n = t.block[0]
        if t.src == "O" and n not in (1, FFFF):
            if n - 1 not in acked_in or acked_in[n - 1] >= t.poll:
                out.append(n)
    return sorted(set(out))


class WindowStates:
    """A bench part: MIP_Sender's eWindow after every scan, and the changes between scans."""

    def __init__(self, u):
        self.snd, self.states, self.steps = u.snd, [], set()

    def after_scan(self):
        w = self.snd["eWindow"]
        if self.states and self.states[-1] != w:
            self.steps.add((self.states[-1], w))
        self.states.append(w)


def run(u, window, limit=20000):
    u.snd["uWindow"] = window
    u.bench.step(3)
    start = u.bench.scans
    result = u.send(limit)
    return result, u.bench.scans - start


def test_window_2_pipelines_and_delivers_exactly(wd):
    data = pattern(30 * 122, seed=900)
    u1 = Uni(wd, data)
    r1, scans1 = run(u1, 1)
    u2 = Uni(wd, data)
    r2, scans2 = run(u2, 2)
    assert r1 == r2 == "done"
    assert u1.sink.transfers == [data] and u2.sink.transfers == [data]
    assert pipelined(u1.radio) == []
    assert u1.snd["eWindow"] == u2.snd["eWindow"] == WIN["MIP_WIN_SINGLE"]
    assert u1.snd["udiLoopOverruns"] == u2.snd["udiLoopOverruns"] == 0
    # from record 2 on every record but the last goes up before the acknowledgement of the
    # one before it (record 2 waits for ack 1: P27, a stale ack 2 could pass for it)
    assert pipelined(u2.radio) == list(range(3, 30))
    assert u2.snd["udiRecords"] == 30 and u2.snd["udiRetransmissions"] == 0
    assert scans2 < 0.65 * scans1, (scans1, scans2)


def test_window_2_goes_back_when_the_receiver_reads_too_slowly(wd):
    """The central reads its modem every 12 scans, the radio polls every 5: a pipelined record
    overwrites the one before before it is read. The receiver ignores the unexpected number,
    the sender's retransmission goes back to the older record and closes the window for the
    next 8 acknowledged records: nothing lost, nothing twice, about one retransmission per 8
    records."""
    data = pattern(30 * 122, seed=901)
    u = Uni(wd, data, timeout_ms=300)
    u.port_c.read_every = 12
    seen = WindowStates(u)
    u.bench.parts.append(seen)
    result, _ = run(u, 2, limit=40000)
    assert result == "done" and u.sink.transfers == [data]
    # eWindow showed each state, and only the steps P27 allows: single -> ahead (pipelined),
    # ahead -> single (acknowledged), ahead -> back (retransmission), back -> single
    assert set(seen.states) == set(WIN.values())
    assert seen.steps <= {(WIN["MIP_WIN_SINGLE"], WIN["MIP_WIN_AHEAD"]),
                          (WIN["MIP_WIN_AHEAD"], WIN["MIP_WIN_SINGLE"]),
                          (WIN["MIP_WIN_AHEAD"], WIN["MIP_WIN_BACK"]),
                          (WIN["MIP_WIN_BACK"], WIN["MIP_WIN_SINGLE"])}, seen.steps
    assert u.snd["udiLoopOverruns"] == 0
    assert [n for n, _ in u.sink.records] == list(range(1, 30)) + [FFFF]
    assert u.rcv["udiUnexpected"] >= 1          # a pipelined record arrived before its turn
    assert 1 <= u.snd["udiRetransmissions"] <= 30 // 8 + 2
    ups = records_up(u.radio)
    first_back = next(i for i in range(1, len(ups)) if ups[i] < ups[i - 1])
    assert pipelined(u.radio)                    # it did pipeline before that
    back_at = [i for i, t in enumerate(u.radio.log) if t.src == "O"][first_back]
    n0 = ups[first_back]
    # the 8 records after the one it went back to go stop and wait
    assert [n for n in pipelined(u.radio, back_at) if n0 + 1 < n <= n0 + 8] == []


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_window_2_exact_under_loss_and_duplicates(wd, seed):
    data = pattern(20 * 122 + 17, seed=910 + seed)
    rnd = random.Random(seed)
    u = Uni(wd, data, timeout_ms=300,
            fate=lambda src, block: rnd.choices(["ok", "lost", "dup"], [6, 2, 2])[0])
    result, _ = run(u, 2, limit=60000)
    assert result == "done" and u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == list(range(1, 21)) + [FFFF]


def test_window_2_against_a_strict_note_central(wd):
    """Wire-compatible: a central written from the note alone accepts the pipelined records."""
    data = pattern(15 * 122, seed=920)
    u, note = uni_vs_note_central(wd, data)
    result, _ = run(u, 2)
    assert result == "done"
    assert [n for n, _ in note.records] == list(range(1, 15)) + [FFFF]
    got = [v for _, p in note.records for v in p]
    assert got == data
    assert pipelined(u.radio)


def test_window_2_slow_note_central_still_completes(wd):
    """The livelock the model finds when the window stays open (PIPE_KEEP): a note central
    slower than the radio never sees a record that the next one overwrote; closing the window
    after the first retransmission ends it."""
    data = pattern(10 * 122, seed=921)
    u, note = uni_vs_note_central(wd, data)
    note.every = 12
    result, _ = run(u, 2, limit=40000)
    assert result == "done"
    assert [v for _, p in note.records for v in p] == data


@pytest.mark.parametrize("mode", ["polled", "static"])
def test_window_2_is_stop_and_wait_where_it_does_not_apply(wd, mode):
    data = pattern(8 * 61, seed=930)
    kw = {"polled": dict(polled=True), "static": dict(static_n=62, chunk=62)}[mode]
    u = Uni(wd, data, **kw)
    result, _ = run(u, 2)
    assert result == "done" and u.sink.transfers == [data]
    assert pipelined(u.radio) == []


def test_window_2_applies_to_a_retained_sender(wd):
    """xRetained (W1) pipelines too since the model checked it with warm restarts
    (warm/win2/...); the restarts themselves: tests/st_lib/test_lib_window_warm.py."""
    data = pattern(8 * 61, seed=930)
    u = Uni(wd, data, chunk=62)
    u.snd["xRetained"] = True
    u.bench.parts.append(_Snapshots(u.snd))
    result, _ = run(u, 2)
    assert result == "done" and u.sink.transfers == [data]
    assert pipelined(u.radio) == list(range(3, 8))


class _Snapshots:
    """A runtime that completes every snapshot the block asks for at the end of the scan."""

    def __init__(self, fb):
        self.fb, self.n = fb, 0

    def after_scan(self):
        if self.fb["xSnapshotReq"]:
            self.n = (self.n + 1) % 65536
            self.fb["wSnapshots"] = self.n


def test_window_is_latched_at_the_start(wd):
    """P26: uWindow set to 2 mid-transfer changes nothing; the next transfer pipelines. The
    chunks are asked for once each, in order, also ahead of time."""
    data = pattern(10 * 122, seed=940)
    u = Uni(wd, data)
    u.snd["uWindow"] = 1
    u.snd["xExecute"] = False
    u.bench.step()
    u.snd["xExecute"] = True
    u.bench.step(5)
    u.snd["uWindow"] = 2
    assert u.bench.run_until(lambda: u.snd["xDone"], 20000)
    assert pipelined(u.radio) == []
    u.snd["xExecute"] = False
    u.bench.step(2)
    first = len(u.radio.log)
    assert u.send() == "done"
    assert u.sink.transfers == [data, data]
    assert pipelined(u.radio, first) == list(range(3, 10))
    assert u.src.served == list(range(10)) * 2


def test_buffer_sender_passes_the_window_on(wd):
    """MIP_BufferSender.uWindow goes to its MIP_Sender: 12 records of its buffer pipelined."""
    u = Uni(wd, buffer=True, timeout_ms=300)
    u.plc_o["MAIN.bs_seed"] = 5
    u.plc_o["MAIN.bs_fill"] = True
    u.bench.step(1)
    u.plc_o["MAIN.bs_fill"] = False
    u.snd["udiLength"] = 12 * 122
    u.snd["uWindow"] = 2
    assert u.send() == "done"
    want = [(i * 7 + 5) % 65536 for i in range(12 * 122)]
    assert u.sink.transfers == [want]
    assert pipelined(u.radio) == list(range(3, 12))
