"""Our blocks against peers that follow only the Piciorgros note (st_lib/PROTOCOL.md): a note
central / outstation played in Python on the emulated modems of stlib_sim.py, strict (only
the next number counts) or lenient (record 1 always starts a new transfer). Also the echo
check (P8), the bidirectional own-modem rule (P9), the out-of-step bounds (P11, P21) and the
per-record reaction (P25). Virtual time: 10 ms scans, radio poll every 5 scans."""
from pathlib import Path

import pytest

from stlib_sim import ERR, FFFF, MS, SND, WAIT, Bi, Uni, pattern

E_NONE, E_PEER_RESET, E_SENDER_RESET, E_OUT_OF_STEP = (
    ERR["MIP_ERR_" + n] for n in ("NONE", "PEER_RESET", "SENDER_RESET", "PEER_OUT_OF_STEP"))
S_WAIT_ACK, S_ERROR = SND["MIP_SND_WAIT_ACK"], SND["MIP_SND_ERROR"]
W_ACK, W_CONFIRM, W_OUT_OF_STEP, W_RECORD = (
    WAIT["MIP_WAIT_" + n] for n in ("ACK", "CONFIRM", "OUT_OF_STEP", "RECORD"))
MAGIC = 0x4D50


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_interop")


def check(block):
    """The check value of PROTOCOL.md section 1 (unidirectional: every register counts)."""
    c = len(block)
    for r in block:
        c ^= r
        c = ((c << 5) | (c >> 11)) & 0xFFFF
    return c


class NoteCentral:
    """A central written from the note alone: reads its modem every `every` scans; a new
    telegram with the next number (strict) - or record 1 (lenient) - is accepted; every new
    telegram is answered with the last accepted number, one register (note 2.1)."""

    def __init__(self, modem, strict=True, last=0, every=2):
        self.m, self.strict, self.L, self.every = modem, strict, last, every
        self.records, self.k = [], 0

    def after_scan(self):
        self.k += 1
        if self.k % self.every:
            return
        blk = self.m.read125()
        if not blk[0] & 1 or blk[1] < 1:
            return
        n, payload = blk[2], blk[3:2 + blk[1]]
        nxt = (n == 1 and self.L in (0, FFFF)) or (self.L not in (0, FFFF) and n in (self.L + 1, FFFF))
        if nxt or (not self.strict and n == 1 and n != self.L):
            self.L = n
            self.records.append((n, payload))
        self.m.write([self.L])


class NoteOutstation:
    """An outstation sender written from the note alone (spontaneous): writes record n, repeats
    it every `repeat` scans until its number comes back, then the next one."""

    def __init__(self, modem, records, repeat=30, every=2):
        self.m, self.todo, self.repeat, self.every = modem, list(records), repeat, every
        self.k = self.since = 0
        self.cur = None

    def after_scan(self):
        self.k += 1
        self.since += 1
        if self.k % self.every == 0 and self.cur is not None:
            blk = self.m.read125()
            if blk[1] >= 1 and blk[2] == self.cur[0]:
                self.cur = None
        if self.cur is None and self.todo:
            self.cur = self.todo.pop(0)
            self.since = self.repeat
        if self.cur is not None and self.since >= self.repeat:
            self.m.write(list(self.cur))
            self.since = 0


def uni_vs_note_central(wd, data, strict=True, last=0, timeout_ms=300):
    """Our MIP_Sender on the outstation, a note central on the MDP."""
    u = Uni(wd, data, timeout_ms=timeout_ms, enable=False)
    note = NoteCentral(u.mc, strict, last)
    u.bench.parts = [p for p in u.bench.parts if p not in (u.port_c, u.sink)] + [note]
    u.bench.check_plcopen = u.bench.check_plcopen[:1]
    return u, note


def uni_vs_note_outstation(wd, records, timeout_ms=300):
    """A note outstation sender, our MIP_Receiver on the central."""
    u = Uni(wd, [], timeout_ms=timeout_ms)
    note = NoteOutstation(u.mo, records)
    u.bench.parts = [p for p in u.bench.parts if p not in (u.port_o, u.src)] + [note]
    u.bench.check_plcopen = u.bench.check_plcopen[1:]
    return u, note


# ---------------------------------------------------------------- our sender, note central

def test_sender_against_note_central_session_opens_with_record_1(wd):
    """The note's read-out: record 1 is the first thing our sender puts on the air, in the
    first radio poll after xExecute; the note central gets every record once, in order."""
    data = pattern(3 * 122 + 9, seed=301)
    u, note = uni_vs_note_central(wd, data)
    u.mo.receive([0])                  # the central asked with acknowledgement 0
    u.bench.step(3)
    start = u.bench.scans
    assert u.send() == "done"
    sent_o = [t.block[0] for t in u.radio.log if t.src == "O"]
    assert sent_o == [1, 2, 3, FFFF]
    first = next(i for i, t in enumerate(u.radio.log) if t.src == "O")
    assert first == 0 and u.bench.scans > start
    assert [n for n, _ in note.records] == [1, 2, 3, FFFF]
    assert sum((p for _, p in note.records), []) == data


def test_restarted_sender_vs_strict_note_central_errors_within_the_bound(wd):
    """Issue 11 case 1: our outstation restarted mid-transfer; the strict note central had
    accepted record 5 and acknowledges 5 forever while we send record 1. With unlimited
    retries the sender still ends in xError (MIP_ERR_PEER_OUT_OF_STEP) after 3 x tTimeout of
    only such acknowledgements; meanwhile eWaitReason says why it waits."""
    u, note = uni_vs_note_central(wd, pattern(3 * 122, seed=302), strict=True, last=5)
    u.mo.receive([5])
    u.snd["uMaxRetries"] = 0
    u.bench.step(3)
    u.snd["xExecute"] = True
    t0 = u.plc_o.time_ns
    assert u.bench.run_until(lambda: u.snd["eState"] == S_WAIT_ACK, 50)
    u.bench.step(10)
    assert u.snd["eWaitReason"] == W_OUT_OF_STEP and u.snd["wLastAck"] == 5
    assert u.bench.run_until(lambda: u.snd["xError"], 400)
    elapsed_ms = (u.plc_o.time_ns - t0) / MS
    assert u.snd["eErrorId"] == E_OUT_OF_STEP
    assert 900 <= elapsed_ms <= 900 + 100, elapsed_ms
    assert note.records == []


def test_restarted_sender_vs_lenient_note_central_completes(wd):
    """The same restart against a lenient note central (record 1 starts anew): complete."""
    data = pattern(2 * 122 + 1, seed=303)
    u, note = uni_vs_note_central(wd, data, strict=False, last=5)
    u.mo.receive([5])
    u.bench.step(3)
    assert u.send() == "done"
    assert sum((p for _, p in note.records), []) == data


def test_note_receiver_ack_counts_by_number_alone(wd):
    """P8 degrades to the note: an acknowledgement without our echo counts by its number."""
    u = Uni(wd, pattern(2 * 122, seed=304), timeout_ms=300,
            fate=lambda src, block: "drop" if src == "O" else "ok")
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["eState"] == S_WAIT_ACK and not u.snd["xWriteReq"], 100)
    u.bench.step(3)
    u.mo.receive([1])                  # a note central's one-register acknowledgement
    assert u.bench.run_until(lambda: u.snd["udiRecords"] == 1, 20)


def test_stale_ack_with_wrong_check_is_ignored(wd):
    """P8: an acknowledgement 1 with our echo but the check value of another record 1 (left
    from before a restart) does not count; the receiver's real acknowledgement does."""
    data = pattern(2 * 122, seed=305)
    u = Uni(wd, data, timeout_ms=300, fate=lambda src, block: "drop" if src == "O" else "ok")
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["eState"] == S_WAIT_ACK and not u.snd["xWriteReq"], 100)
    rec1 = u.port_o.writes[-1]
    assert rec1[0] == 1
    u.bench.step(3)
    u.mo.receive([1, MAGIC, check(rec1) ^ 0x0101])
    u.bench.step(30)
    assert u.snd["udiRecords"] == 0 and u.snd["wRecord"] == 1
    assert u.snd["eWaitReason"] == W_OUT_OF_STEP and u.snd["udiUnexpectedAcks"] >= 1
    u.mo.receive([1, MAGIC, check(rec1)])     # what our receiver writes for this record 1
    assert u.bench.run_until(lambda: u.snd["udiRecords"] == 1, 20)
    u.radio.fate = lambda src, block: "ok"
    u.bench.run_until(lambda: u.snd["xDone"], 2000)
    assert u.snd["xDone"]
    # the receiver saw only the last record (record 1 was acknowledged by the test above): from
    # acknowledgement 2 on it writes the note's one register, no echo (P24)
    assert u.port_c.writes[-1] == [FFFF]


def test_our_receiver_echo_of_record_1_carries_the_senders_check(wd):
    """P8/P24: our receiver's echo of record 1 is [1, 16#4D50, check of the block as the sender
    wrote it] (what lets our sender tell it from a stale one); acknowledgement 0 carries the
    magic with check 0; the acknowledgements after 1 are the note's [ack]."""
    data = pattern(3 * 122, seed=308)
    u = Uni(wd, data, timeout_ms=300)
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.send() == "done"
    rec1 = next(w for w in u.port_o.writes if w[0] == 1)
    acks = u.port_c.writes
    assert acks[0] == [0, MAGIC, 0]
    assert [1, MAGIC, check(rec1)] in acks
    assert [w for w in acks if w[0] not in (0, 1)] == [[2], [FFFF]]


def test_stale_ack_after_sender_restart_cannot_mix_transfers(wd):
    """Sender restarts right after record 1 of transfer A was accepted (L = 1); transfer B's
    record 1 is lost on the radio once, while the receiver keeps repeating its echo of A's
    record 1: B's sender must not count it, and B arrives whole (record 1 of B replaces A)."""
    a, b = pattern(3 * 122, seed=306), pattern(2 * 122 + 5, seed=307)
    u = Uni(wd, a, timeout_ms=300)
    u.bench.step(3)
    u.src.hold_from = 1
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.rcv["udiRecords"] == 1 and u.mo.read_area[0] == 1, 500)
    u.restart_outstation()
    u.src.data, u.src.hold_from = b, None
    drops = {"n": 0}

    def fate(src, block):
        if src == "O" and block[0] == 1 and drops["n"] < 1:
            drops["n"] += 1
            return "drop"
        return "ok"
    u.radio.fate = fate
    assert u.send() == "done"
    assert u.sink.transfers == [b]
    assert u.rcv["udiFailedTransfers"] == 1 and u.rcv["eLastErrorId"] == E_SENDER_RESET


# ---------------------------------------------------------------- note outstation, our receiver

def test_lone_ffff_is_a_one_record_transfer(wd):
    """Issue 11 case 2: a note outstation sends its only record as a lone 16#FFFF after our
    central acknowledged 0: delivered and completed. A second lone 16#FFFF with other content
    is the next transfer; the same block again is a duplicate."""
    p1, p2 = pattern(40, seed=308), pattern(7, seed=309)
    u, note = uni_vs_note_outstation(wd, [[FFFF] + p1])
    assert u.bench.run_until(lambda: u.rcv["xTransferComplete"], 300)
    assert u.sink.transfers == [p1] and u.rcv["wAck"] == FFFF
    assert u.port_c.writes[-1] == [FFFF]      # the note's acknowledgement, no echo (P24)
    note.todo.append([FFFF] + p2)
    assert u.bench.run_until(lambda: len(u.sink.transfers) == 2, 300)
    assert u.sink.transfers == [p1, p2] and u.rcv["udiTransfers"] == 2
    u.mo.write([FFFF] + p2)            # the same block again (the link repeated it)
    u.bench.step(30)
    assert len(u.sink.transfers) == 2 and u.rcv["udiDuplicates"] >= 1


def test_note_outstation_record_1_restarts_the_transfer(wd):
    """A (lenient-style) note outstation restarts mid-transfer and sends record 1 again:
    the open transfer is reported failed, the new one arrives whole."""
    old = [[1, 11], [2, 12], [3, 13]]
    new = [[1, 21], [2, 22], [FFFF, 23]]
    u, note = uni_vs_note_outstation(wd, old)
    assert u.bench.run_until(lambda: u.rcv["wAck"] == 3, 500)
    note.todo, note.cur = list(new), None
    assert u.bench.run_until(lambda: u.rcv["xTransferComplete"], 500)
    assert u.sink.transfers == [[21, 22, 23]]
    assert u.rcv["udiFailedTransfers"] == 1 and u.rcv["eLastErrorId"] == E_SENDER_RESET


def test_receiver_out_of_step_error_and_its_clearing(wd):
    """P21: our central restarted (acknowledges 0) while a strict note outstation keeps
    repeating record 6: after 3 x tTimeout of only such telegrams, xError with
    MIP_ERR_PEER_OUT_OF_STEP; it clears when a record is accepted."""
    u, note = uni_vs_note_outstation(wd, [[6, 66]])
    # the first block read after enabling does not count (P21); its repetition (every 300 ms)
    # starts the run of unexpected telegrams
    assert u.bench.run_until(lambda: u.rcv["eWaitReason"] == W_OUT_OF_STEP, 100)
    t0 = u.plc_c.time_ns
    assert not u.rcv["xError"]
    assert u.bench.run_until(lambda: u.rcv["xError"], 300)
    elapsed_ms = (u.plc_c.time_ns - t0) / MS
    assert u.rcv["eErrorId"] == E_OUT_OF_STEP and u.rcv["wAck"] == 0
    assert 900 <= elapsed_ms <= 900 + 300 + 50, elapsed_ms     # the bound + one repetition
    assert u.sink.records == []
    note.todo, note.cur = [[1, 1], [FFFF, 2]], None     # the operator restarts the outstation
    assert u.bench.run_until(lambda: u.rcv["xTransferComplete"], 500)
    assert not u.rcv["xError"] and u.sink.transfers == [[1, 2]]


def test_idle_stale_read_area_raises_no_out_of_step(wd):
    """What sits in the read area when the receiver starts is not a telegram of this session:
    an idle area (the last transfer's 16#FFFF) gives no delivery and no error, however long."""
    u = Uni(wd, [], timeout_ms=100)
    u.mc.receive([FFFF, 1, 2])
    u.bench.step(200)
    assert not u.rcv["xError"] and u.sink.records == [] and u.rcv["eWaitReason"] == W_RECORD


def test_stale_read_area_mid_transfer_raises_out_of_step_after_the_bound(wd):
    """P21: a first block that shows a sender mid-transfer (record 7) and nothing in step after
    it (a static-mode sender never sends its unchanged block again): xError with
    MIP_ERR_PEER_OUT_OF_STEP after 3 x tTimeout, nothing delivered; record 1 clears it."""
    u = Uni(wd, [], timeout_ms=100)
    u.mc.receive([7, 1, 2])
    u.bench.step(20)
    assert not u.rcv["xError"] and u.rcv["eWaitReason"] == W_OUT_OF_STEP
    assert u.bench.run_until(lambda: u.rcv["xError"], 100)
    assert u.rcv["eErrorId"] == E_OUT_OF_STEP and u.rcv["wAck"] == 0 and u.sink.records == []
    u.mc.receive([1, 5, 6])
    assert u.bench.run_until(lambda: not u.rcv["xError"], 50)
    assert [n for n, _ in u.sink.records] == [1]


def test_restarted_receiver_with_cyclic_reads_does_not_redeliver_the_last_record(wd):
    """P19 with a cyclic master (OpenPLC): after a PLC restart the input image is empty for a
    few scans (xReadValid TRUE, count 0), then shows the previous transfer's 16#FFFF, already
    delivered: that is the first block, not a lone one-record transfer."""
    data = pattern(60, seed=312)
    u = Uni(wd, data, read_mode="cyclic", read_every=3)
    u.bench.step(3)
    assert u.send() == "done" and u.sink.transfers == [data]
    u.bench.step(20)
    u.port_c._k = 3 * (u.port_c._k // 3 + 1)     # the next refresh is 3 scans away
    u.restart_central()
    u.bench.step(100)
    assert u.sink.transfers == [data] and [n for n, _ in u.sink.records] == [1]
    assert not u.rcv["xError"] and u.rcv["wAck"] == 0


# ---------------------------------------------------------------- bidirectional: P9

def test_bidirectional_stale_ack_counts_only_after_own_modem_confirmed(wd):
    """P9: the central's acknowledgement 1 arrives while our record 1 still waits in the own
    modem (radio stopped): not counted (eSendWaitReason = MIP_WAIT_CONFIRM). Once the record
    is delivered and confirmed the transfer runs; the central gets record 1 once."""
    data = pattern(2 * 121 + 4, seed=310)
    bi = Bi(wd, data, [], timeout_ms=300)
    radio, bi.bench.radio = bi.radio, None
    bi.bench.step(3)
    bi.lo["xExecute"] = True
    assert bi.bench.run_until(lambda: bi.mo.unconfirmed and bi.mo.write_area[0] == 1
                              and not bi.lo["xWriteReq"], 100)
    bi.mo.receive([1, 0])              # a stale acknowledgement 1 (central block: [ack, its record])
    bi.bench.step(30)
    assert bi.lo["udiRecordsSent"] == 0 and bi.lo["eSendWaitReason"] == W_CONFIRM
    bi.bench.radio = radio
    assert bi.bench.run_until(lambda: bi.lo["xSendDone"], 3000)
    assert bi.sink_c.transfers == [data]
    assert [n for n, _ in bi.sink_c.records] == [1, 2, FFFF]


# ---------------------------------------------------------------- P25: reaction

@pytest.mark.parametrize("polled,buffer", [(False, False), (True, False), (False, True)])
def test_one_scan_from_ack_to_next_write_request(wd, polled, buffer):
    """P25: the scan that reads (and counts) the acknowledgement asks for the next chunk; the
    chunk arrives in the following scan (MIP_BufferSender: its own next call) and the write
    request rises in that scan."""
    data = pattern(6 * 122, seed=311)
    u = Uni(wd, data, polled=polled, timeout_ms=300, buffer=buffer)
    if buffer:
        u.snd["udiLength"] = 6 * 122
    events = []

    class Probe:
        def after_scan(self, u=u):
            events.append((u.bench.scans, u.snd["udiRecords"], u.snd["xWriteReq"]))
    u.bench.parts.append(Probe())
    u.bench.step(3)
    assert u.send() == "done"
    gaps = []
    for i in range(1, len(events)):
        scan, recs, _ = events[i]
        if recs > events[i - 1][1] and recs < 6:
            nxt = next(s for s, r, req in events[i:] if req)
            gaps.append(nxt - scan)
    assert len(gaps) == 5 and max(gaps) <= 1, gaps
