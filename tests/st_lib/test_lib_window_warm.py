"""MIP_Sender with uWindow = 2 and xRetained (st_lib/PROTOCOL.md P27 with W1/W3): the pipelined
record is a new record like any other, its first write waits for a snapshot that holds it, and
the pipelined state is part of the retained instance. Checked in the model first
(model/, configurations warm/win2/... hold; warm-win2-nogate and warm-win2-norestore must
fail). Here: the block on the emulated network, the outstation's program RETAIN, warm restarts
(back to the last snapshot, as after a kill -9 of plcrt) at random scans."""
import random
from pathlib import Path

import pytest

from stlib_sim import Uni, build_text, gen_program, pattern
from test_lib_warm import first_writes_follow_a_snapshot
from test_lib_window import pipelined


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_window_warm")


RETAINED = gen_program([("snd", "MIP_Sender")]).replace("VAR\n", "VAR RETAIN\n", 1)


class Runtime:
    """plcrt's snapshots for the outstation PLC: one taken at the end of every scan whose
    xSnapshotReq is TRUE, others now and then (the periodic save, `periodic` per scan), taken
    between two scans and counted in wSnapshots from the next scan on (plcrt, docs/retain.md);
    the count starts again from 0 after a restart. A restart (the PLC killed) comes after the
    scan's writes went out and before its snapshot: a write of that scan is on the radio, the
    state that made it is lost unless an earlier snapshot holds it. `restart`
    per scan: a warm restart back to the last snapshot (the modems keep running); `after_new`:
    the chance of one in the scan that first wrote a number (the moment W1 is about)."""

    def __init__(self, u, wd, rnd, periodic=0.0, restart=0.0, after_new=0.0):
        self.u, self.wd, self.rnd = u, wd, rnd
        self.periodic, self.restart, self.after_new = periodic, restart, after_new
        self.written = set()
        self.count, self.image, self.restarts = 0, None, 0
        self.log = []                       # ("snapshot", None) / ("write", number), in order
        self.seen = 0

    def before_scan(self):
        self.u.snd["wSnapshots"] = self.count & 0xFFFF

    def after_scan(self):
        u = self.u
        new = False
        for block in u.port_o.writes[self.seen:]:
            self.log.append(("write", block[0]))
            new = new or block[0] not in self.written
            self.written.add(block[0])
        self.seen = len(u.port_o.writes)
        if self.image is not None and (self.rnd.random() < self.restart
                                       or (new and self.rnd.random() < self.after_new)):
            self.warm_restart()
        elif u.snd["xSnapshotReq"] or self.rnd.random() < self.periodic:
            self.count += 1
            self.image = u.plc_o.retain_save()
            self.log.append(("snapshot", None))

    def warm_restart(self):
        u = self.u
        new = build_text(RETAINED, self.wd, "build_retained")
        new.retain_load(self.image)
        u.bench.plcs[u.bench.plcs.index(u.plc_o)] = new
        u.plc_o = u.snd.plc = new
        u.port_o._done = u.port_o._err = False     # the runtime's write handshake starts anew
        u.snd["xWriteDone"] = u.snd["xWriteError"] = False
        self.count = 0
        self.restarts += 1
        self.log.append(("restart", None))


class SlowCaller:
    """The caller hands a chunk over only after the request has been up for 0..`most` scans
    (drawn anew for each): the chunk taken ahead of time may then arrive after the own modem
    confirmed the record in flight, and the block could write it in the scan it took it."""

    def __init__(self, src, rnd, most):
        self.src, self.rnd, self.most = src, rnd, most
        self.waited, self.wait = 0, rnd.randint(0, most)

    def before_scan(self):
        fb = self.src.fb
        if fb["xChunkRequest"] and not fb["xChunkValid"] and self.waited < self.wait:
            self.waited += 1
            self.src.hold_from = fb["udiChunkIndex"]     # not yet
        else:
            if self.src.hold_from is not None:
                self.waited, self.wait = 0, self.rnd.randint(0, self.most)
            self.src.hold_from = None


def retained_sender(wd, data, rnd, slow=0, **kw):
    u = Uni(wd, data)
    if slow:
        u.bench.parts.insert(0, SlowCaller(u.src, rnd, slow))
    plc = build_text(RETAINED, wd, "build_retained")
    u.bench.plcs[u.bench.plcs.index(u.plc_o)] = plc
    u.plc_o = u.snd.plc = plc
    u.configure_sender()
    u.snd["xRetained"] = True
    u.snd["uWindow"] = 2
    rt = Runtime(u, wd, rnd, **kw)
    u.bench.parts.append(rt)
    return u, rt


def test_window_2_retained_pipelines_each_record_after_its_snapshot(wd):
    """W1 for the pipelined record: every first write of a number follows a snapshot taken
    after the number before it was first written; and window 2 still pipelines."""
    data = pattern(10 * 122, seed=950)
    u, rt = retained_sender(wd, data, random.Random(1))
    assert u.send(20000) == "done"
    assert u.sink.transfers == [data]
    firsts = first_writes_follow_a_snapshot([("snd",) + ev for ev in rt.log], "snd")
    order = list(dict.fromkeys(number for kind, number in rt.log if kind != "snapshot"))
    assert order == list(range(1, 10)) + [0xFFFF] and set(order) == firsts
    assert pipelined(u.radio) == list(range(3, 10))   # from record 3 on, the last one waits
    assert rt.count == 10                             # one snapshot per record, none more


def test_window_2_retained_waits_for_the_snapshot_before_the_pipelined_write(wd):
    """A runtime that stops completing snapshots: the record in flight is repeated, the
    pipelined one never goes out; once snapshots complete again the transfer ends."""
    data = pattern(6 * 122, seed=951)
    u, rt = retained_sender(wd, data, random.Random(2))
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["udiRecords"] >= 2, 5000)
    n = len(u.port_o.writes)
    count = rt.count
    orig = rt.after_scan

    def no_snapshots():
        orig()
        rt.count, rt.image = count, rt.image     # the request is never completed
    rt.after_scan = no_snapshots
    u.bench.step(300)
    later = {b[0] for b in u.port_o.writes[n:]}
    built = max(b[0] for b in u.port_o.writes[:n])
    assert later <= {built}, later                 # only repeats of the record in flight
    assert u.snd["xSnapshotReq"]
    rt.after_scan = orig
    assert u.bench.run_until(lambda: u.snd["xDone"] or u.snd["xError"], 20000)
    assert u.snd["xDone"] and u.sink.transfers == [data]


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_window_2_retained_warm_restarts_at_random_scans_lose_and_double_nothing(wd, seed):
    """Warm restarts at random scans, more often right after a record's first write (also the
    pipelined one's: back to the snapshot that holds it built, model warm/win2/...; without
    that snapshot the rollback goes to the record before it, which the receiver has passed:
    warm-win2-nogate); a caller that hands chunks over late; periodic snapshots besides the
    requested ones:
    every record arrives exactly once, the transfer ends done, nothing fails."""
    rnd = random.Random(seed)
    data = pattern(16 * 122, seed=960 + seed)
    u, rt = retained_sender(wd, data, rnd, slow=12, periodic=0.05, restart=0.03, after_new=0.3)
    u.snd["xExecute"] = False
    u.bench.step()
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["xDone"] or u.snd["xError"], 60000)
    assert u.snd["xDone"], f"error {u.snd['eErrorId']} after {rt.restarts} restarts"
    assert u.sink.transfers == [data]
    assert not u.rcv["xError"]
    assert rt.restarts >= 3
    assert pipelined(u.radio) != []
