"""Warm restarts, the blocks' side (st_lib/PROTOCOL.md W1, W2, W4): with xRetained a new record
goes out, and an acknowledgement is written, only after a snapshot holds it. The runtime's
durability handshake (plcrt `[retain] request` / `saved`) is played by `Snapshots` below: a
snapshot at the end of every scan in which the block asks for one, its count visible in the
next scan. What a rollback to such a snapshot does is checked in the protocol model
(`warm/...` configurations) and in the co-simulation's warm soak."""
import random
from pathlib import Path

import pytest

from stlib_sim import FFFF, WAIT, Bi, Uni, pattern

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


# ---------------------------------------------------------------- MIP_Link (W4)
# Every write of MIP_Link carries both parts' state: its sending part's record image and its
# receiving part's acknowledgement. W4: a write goes out only when the last snapshot holds
# both; while either part has a change no snapshot holds yet, no write starts, also not one the
# other part asks for.

class LinkWatch:
    """Per scan, what a link's write would carry (the sending part's counter in the image and
    the acknowledgement) and when it last changed; the snapshots by scan; each write by scan."""

    def __init__(self, bench, fb, port, snaps, stream):
        self.bench, self.fb, self.port, self.snaps = bench, fb, port, snaps
        self.stream, self.other = stream, 1 - stream
        self.state, self.changed = None, 0
        self.snap_scans, self.writes = [], []        # writes: (scan, block, state changed at)
        self._seen, self._count = 0, 0

    def after_scan(self):
        k = self.bench.scans
        state = (self.fb[f"snd.aWrite[{self.stream}]"], self.fb["wAck"])
        if state != self.state:
            self.state, self.changed = state, k
        if self.snaps.count != self._count:          # Snapshots.after_scan ran before: this scan's
            self._count = self.snaps.count
            self.snap_scans.append(k)
        for block in self.port.writes[self._seen:]:
            self.writes.append((k, block, self.changed))
        self._seen = len(self.port.writes)

    def unsaved_writes(self):
        """Writes whose content changed in a scan no completed snapshot followed before the
        write's scan (a snapshot at the end of scan j is seen from scan j + 1)."""
        return [(k, b[:2]) for k, b, c in self.writes
                if not any(c <= j < k for j in self.snap_scans)]


def retained_link(wd, up, down, fate=None):
    b = Bi(wd, up, down, fate=fate)
    for fb in (b.lo, b.lc):
        fb["xRetained"] = True          # sampled at xEnable's rising edge: before the first scan
    log = []
    so, sc = Snapshots(b.lo, log, "O"), Snapshots(b.lc, log, "C")
    wo = LinkWatch(b.bench, b.lo, b.port_o, so, 0)
    wc = LinkWatch(b.bench, b.lc, b.port_c, sc, 1)
    b.bench.parts[0:0] = [so, sc]
    b.bench.parts += [wo, wc]
    return b, so, sc, wo, wc


def test_link_starts_no_write_while_its_receiving_part_is_unsaved(wd):
    """The central's receiving part accepted a record no snapshot holds yet, and its sending
    part's record needs a retransmission (the central's blocks are lost on the way down): no
    write starts, the retransmission included (it would carry the unsaved acknowledgement),
    until wSnapshots changes; then one write carries both."""
    up, down = pattern(2 * 121, seed=61), pattern(12 * 121, seed=62)
    drop = {"C": False}
    b, so, sc, wo, wc = retained_link(wd, up, down,
                                      fate=lambda src, block: "drop" if drop.get(src) else "ok")
    lc, lo = b.lc, b.lo
    lc["xExecute"] = True               # the outstation's stream stays idle for now

    seen = [0]

    def new_record_written():          # in the scan just run: record 2 or later, first write
        w, n = b.port_c.writes, seen[0]
        seen[0] = len(w)
        return len(w) == n + 1 and n >= 1 and w[-1][1] >= 2 and w[-1][1] != w[-2][1]
    assert b.bench.run_until(new_record_written, 3000)
    rec = lc["wRecord"]
    # from now on the central's blocks never reach the outstation (record `rec` is lost), and
    # the central's runtime saves nothing; the outstation starts its transfer
    drop["C"], sc.enabled = True, False
    writes0, retr0, snaps0 = len(b.port_c.writes), lc["udiRetransmissions"], sc.count
    lo["xExecute"] = True
    assert b.bench.run_until(lambda: lc["wAck"] == 1, 500)          # accepted, no snapshot holds it
    assert lc["xSnapshotReq"] and lc["rcv.xSnapshotReq"]
    assert b.bench.run_until(lambda: lc["udiRetransmissions"] > retr0, 500)
    assert lc["snd.xWriteReq"] and lc["wRecord"] == rec            # the sending part asks ...
    b.bench.step(40)
    assert len(b.port_c.writes) == writes0, "a write went out with an acknowledgement no snapshot holds"
    assert not lc["xWriteReq"]                                     # ... and the link holds it
    assert lc["eSendWaitReason"] == MIP_WAIT_SNAPSHOT and lc["eRecvWaitReason"] == MIP_WAIT_SNAPSHOT
    # the runtime saves again: the scan after the snapshot starts the held write
    sc.enabled = True
    assert b.bench.run_until(lambda: len(b.port_c.writes) > writes0, 3)
    assert sc.count == snaps0 + 1
    assert b.port_c.writes[writes0][:2] == [1, rec]      # the new acknowledgement, our record again
    assert wc.unsaved_writes() == [] and wo.unsaved_writes() == []
    drop["C"] = False
    assert b.bench.run_until(lambda: lc["xSendDone"] and lo["xSendDone"], 20000)
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert wc.unsaved_writes() == [] and wo.unsaved_writes() == []


@pytest.mark.parametrize("seed", [5, 6])
def test_link_writes_only_what_a_snapshot_holds(wd, seed):
    """Both directions under loss and duplicates: every write of either link carries only state
    a completed snapshot held before the write started (W4; with W1 and W2 of the parts, and the
    sending part's image going empty after its transfer); both transfers arrive exactly once.
    The runtime saves only when asked."""
    rnd = random.Random(seed)
    up, down = pattern(6 * 121, seed=seed), pattern(5 * 121 + 7, seed=seed + 100)
    b, so, sc, wo, wc = retained_link(
        wd, up, down, fate=lambda src, block: rnd.choices(["ok", "lost", "dup", "drop"], [6, 2, 1, 1])[0])
    res = b.send_both(30000)
    b.bench.step(200)                 # the idle links' last writes (their images gone empty)
    assert res == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    for w in (wo, wc):
        assert w.unsaved_writes() == []
        assert {blk[w.stream] for _, blk, _ in w.writes} >= {1, FFFF, 0}
    assert so.count > 6 and sc.count > 6


def test_link_without_xretained_asks_for_no_snapshot(wd):
    up, down = pattern(3 * 121, seed=7), pattern(2 * 121, seed=8)
    b = Bi(wd, up, down)
    asked = []
    b.bench.parts.append(type("Ask", (), {"after_scan": lambda self: asked.append(
        b.lo["xSnapshotReq"] or b.lc["xSnapshotReq"])})())
    assert b.send_both() == ["done", "done"]
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert not any(asked)


def test_link_sending_part_gone_idle_waits_for_a_snapshot(wd):
    """Polled drive: the outstation's receiving part repeats its request every tTimeout with no
    change of its own. When the sending part's transfer is done its image goes empty (0 in our
    counter register): no part asks for a snapshot, but the repeat would carry it, and a
    rollback behind it would bring back the last record, which the peer, having seen 0, could
    take for a new one-record transfer. The link asks for a snapshot first (W4)."""
    up, down = pattern(6 * 121, seed=71), pattern(60, seed=72)
    b, so, sc, wo, wc = retained_link(wd, up, down)
    for fb in (b.lo, b.lc):
        fb["xPolled"] = True             # sampled at xEnable's rising edge: before the first scan
    assert b.send_both(20000) == ["done", "done"]
    b.bench.step(100)                    # the outstation's requests after its transfer
    assert b.sink_c.transfers == [up] and b.sink_o.transfers == [down]
    assert [blk[0] for _, blk, _ in wo.writes][-1] == 0
    assert wo.unsaved_writes() == [] and wc.unsaved_writes() == []
