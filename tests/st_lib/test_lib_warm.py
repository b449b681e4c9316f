"""Warm restarts, the blocks' side (st_lib/PROTOCOL.md W1, W2): with xRetained a new record
goes out, and an acknowledgement is written, only after a snapshot holds it. The runtime's
durability handshake (plcrt `[retain] request` / `saved`) is played by `Snapshots` below: a
snapshot at the end of every scan in which the block asks for one, its count visible in the
next scan. What a rollback to such a snapshot does is checked in the protocol model
(`warm/...` configurations) and in the co-simulation's warm soak."""
from pathlib import Path

import pytest

from stlib_sim import FFFF, WAIT, Uni, pattern

MIP_WAIT_SNAPSHOT = WAIT["MIP_WAIT_SNAPSHOT"]


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_warm")


class Snapshots:
    """The runtime's snapshots for one block: `enabled` FALSE = a runtime that never saves."""

    def __init__(self, fb, log, who, enabled=True):
        self.fb, self.log, self.who, self.enabled = fb, log, who, enabled
        self.count = 0

    def before_scan(self):
        self.fb["wSnapshots"] = self.count & 0xFFFF

    def after_scan(self):
        if self.enabled and self.fb["xSnapshotReq"]:
            self.count += 1
            self.log.append((self.who, "snapshot", None))


class Writes:
    """Logs each block a port wrote, in order with the snapshots."""

    def __init__(self, port, log, who):
        self.port, self.log, self.who, self.seen = port, log, who, 0

    def after_scan(self):
        for block in self.port.writes[self.seen:]:
            self.log.append((self.who, "write", block[0]))
        self.seen = len(self.port.writes)


def retained_pair(wd, data, fate=None, polled=False):
    u = Uni(wd, data, fate=fate, polled=polled)
    u.snd["xRetained"] = True
    u.rcv["xRetained"] = True          # sampled at xEnable's rising edge: before the first scan
    log = []
    so, sc = Snapshots(u.snd, log, "O"), Snapshots(u.rcv, log, "C")
    u.bench.parts[0:0] = [so, sc]
    u.bench.parts += [Writes(u.port_o, log, "O"), Writes(u.port_c, log, "C")]
    return u, so, sc, log


def first_writes_follow_a_snapshot(log, who):
    """Every first write of a new number by `who` came after a snapshot of `who` that was taken
    after the previous new number was written."""
    snap_since, seen = False, set()
    for w, kind, number in log:
        if w != who:
            continue
        if kind == "snapshot":
            snap_since = True
        elif number not in seen:
            assert snap_since, f"{who} wrote {number} before a snapshot held it: {log}"
            seen.add(number)
            snap_since = False
    return seen


def test_nothing_goes_out_while_the_runtime_takes_no_snapshot(wd):
    u, so, sc, log = retained_pair(wd, pattern(2 * 122, seed=3))
    so.enabled = sc.enabled = False
    u.snd["xExecute"] = True
    u.bench.step(80)
    assert u.port_o.writes == [] and u.port_c.writes == []   # neither record 1 nor acknowledgement 0
    for fb in (u.snd, u.rcv):
        assert fb["xSnapshotReq"] and fb["eWaitReason"] == MIP_WAIT_SNAPSHOT
    assert u.snd["wWaitFor"] == 1
    so.enabled = sc.enabled = True
    assert u.bench.run_until(lambda: u.snd["xDone"], 3000)
    assert u.sink.transfers == [pattern(2 * 122, seed=3)]
    assert not u.snd["xSnapshotReq"] and not u.rcv["xSnapshotReq"]


@pytest.mark.parametrize("polled", [False, True])
def test_one_snapshot_before_each_new_record_and_acknowledgement_none_for_repeats(wd, polled):
    data = pattern(3 * 122, seed=11)
    lost = {"done": False}

    def fate(src, block):                  # record 2 lost once: it is written again
        if src == "O" and block[0] == 2 and not lost["done"]:
            lost["done"] = True
            return "drop"
        return "ok"
    u, so, sc, log = retained_pair(wd, data, fate=fate, polled=polled)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["xDone"], 5000)
    assert u.sink.transfers == [data]
    sent = first_writes_follow_a_snapshot(log, "O")
    acked = first_writes_follow_a_snapshot(log, "C")
    assert sent == {1, 2, FFFF} and acked == {0, 1, 2, FFFF}   # 3 chunks: records 1, 2, 16#FFFF
    record_2_writes = [n for w, k, n in log if w == "O" and k == "write" and n == 2]
    assert len(record_2_writes) >= 2          # the repeat ...
    assert so.count == 3                       # ... needed no snapshot: one per new record
    assert sc.count == 4                       # 0 on enable, then 1, 2, 16#FFFF


def test_without_xretained_nothing_waits(wd):
    data = pattern(2 * 122, seed=4)
    u = Uni(wd, data)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["xDone"], 3000)
    assert u.sink.transfers == [data]
    assert not u.snd["xSnapshotReq"] and not u.rcv["xSnapshotReq"]
