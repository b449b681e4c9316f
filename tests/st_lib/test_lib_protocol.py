"""MIP_Sender / MIP_Receiver through the runtime harness, over the emulator core with scripted
telegram fates (tests/st_lib/stlib_sim.py). Virtual time: 10 ms scans, radio poll every 5 scans
unless said."""
from pathlib import Path

import pytest

from stlib_sim import ERR, FFFF, MS, SND, WAIT, Uni, pattern

E_NONE, E_CHUNK_SIZE, E_CHUNK_LEN, E_NO_ACK, E_PEER_RESET, E_TOO_MANY, E_ABORTED, \
    E_SENDER_RESET, E_TRANSFER_TIMEOUT, E_BUFFER_LEN = (
        ERR["MIP_ERR_" + n] for n in ("NONE", "CHUNK_SIZE", "CHUNK_LEN", "NO_ACK", "PEER_RESET",
                                      "TOO_MANY_RECORDS", "ABORTED", "SENDER_RESET",
                                      "TRANSFER_TIMEOUT", "BUFFER_LEN"))
S_IDLE, S_GET_CHUNK, S_WAIT_REQUEST, S_WAIT_ACK, S_DONE, S_ERROR = (
    SND["MIP_SND_" + n] for n in ("IDLE", "GET_CHUNK", "WAIT_REQUEST", "WAIT_ACK", "DONE", "ERROR"))


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib")


def drop_first(src, number, idx=0):
    """A fate: the first telegram from src carrying `number` at register idx is lost for good."""
    state = {"done": False}

    def fate(s, block):
        if not state["done"] and s == src and len(block) > idx and block[idx] == number:
            state["done"] = True
            return "drop"
        return "ok"
    return fate


def until_last_ack(log, src_last="O"):
    """The telegram log up to the central's first acknowledgement of 16#FFFF."""
    out = []
    for t in log:
        out.append(t)
        if t.src != src_last and t.block[0] == FFFF:
            break
    return out


# ---------------------------------------------------------------- the note's example (2.1.1)

def test_note_example_counter_by_counter(wd):
    """Note section 2.1.1: a logger read out in 5 records, the second one lost on the radio.
    The note's records have 126 data registers; Modbus allows 123 per write, so ours carry 122
    (chunk size 123 = counter + 122); the last one carries 50 data registers, as in the note.
    Drive: polled (the central asks with its acknowledgement, as in the note)."""
    data = pattern(4 * 122 + 50, seed=211)
    u = Uni(wd, data, polled=True, timeout_ms=1000, enable=False,
            fate=drop_first("O", 2))
    u.snd["xExecute"] = True
    u.bench.step(2)
    u.rcv["xEnable"] = True          # the central starts asking: acknowledgement 0
    assert u.bench.run_until(lambda: u.snd["xDone"], 3000)
    log = until_last_ack(u.radio.log)
    # The session opens as in the note (st_lib/PROTOCOL.md P6): the central's request 0,
    # then record 1 at once - no reset record, no quiet wait.
    seen = [(t.src, t.block[0], t.fate) for t in log]
    assert seen == [
        ("C", 0, "ok"), ("O", 1, "ok"), ("C", 1, "ok"),
        ("O", 2, "drop"),                     # lost on the radio path
        ("C", 1, "ok"),                       # the central still acknowledges 1 ...
        ("O", 2, "ok"),                       # ... so record 2 is sent again
        ("C", 2, "ok"), ("O", 3, "ok"), ("C", 3, "ok"), ("O", 4, "ok"), ("C", 4, "ok"),
        ("O", FFFF, "ok"), ("C", FFFF, "ok"),
    ]
    o_lengths = [len(t.block) for t in log if t.src == "O"]
    assert o_lengths == [123] * 5 + [51]
    # acknowledgements 0 and 1 carry the echo a note outstation ignores, [ack, 16#4D50, check];
    # from 2 on the note's one register (P8, P24: a stale acknowledgement can only pass for 1)
    c_blocks = [t.block for t in log if t.src == "C"]
    assert all(len(b) == 3 and b[1] == 0x4D50 for b in c_blocks if b[0] in (0, 1))
    assert all(len(b) == 1 for b in c_blocks if b[0] not in (0, 1))
    assert [b[0] for b in c_blocks if len(b) == 1] == [2, 3, 4, FFFF]
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, 4, FFFF]
    assert u.rcv["xTransferComplete"] and u.rcv["wAck"] == FFFF
    assert u.snd["udiRecords"] == 5 and u.snd["udiRetransmissions"] == 1


# ---------------------------------------------------------------- faults, spontaneous drive

def test_lost_record_is_retransmitted_after_timeout(wd):
    data = pattern(3 * 122 + 7, seed=1)
    u = Uni(wd, data, fate=drop_first("O", 2), timeout_ms=300)
    u.bench.step(3)
    assert u.send() == "done"
    assert u.sink.transfers == [data]
    assert [t.block[0] for t in u.radio.log if t.src == "O"].count(2) == 2
    assert u.snd["udiRetransmissions"] == 1
    assert u.rcv["udiDuplicates"] == 0


def test_lost_acknowledgement_duplicate_discarded_and_acknowledged_again(wd):
    data = pattern(3 * 122 + 7, seed=2)
    u = Uni(wd, data, fate=drop_first("C", 2), timeout_ms=300)
    u.bench.step(3)
    assert u.send() == "done"
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, FFFF]    # 2 delivered once
    assert u.rcv["udiDuplicates"] == 1
    assert [t.block[0] for t in u.radio.log if t.src == "C"].count(2) == 2
    assert u.snd["udiRetransmissions"] == 1


def test_link_duplicates_and_repeats(wd):
    """The radio delivers blocks twice (confirmation lost) and repeats lost telegrams."""
    n = {"O": 0, "C": 0}

    def fate(src, block):
        n[src] += 1
        return ("dup", "ok", "lost")[n[src] % 3]
    data = pattern(6 * 122, seed=3)
    u = Uni(wd, data, fate=fate, timeout_ms=400)
    u.bench.step(3)
    assert u.send() == "done"
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, 4, 5, FFFF]
    assert u.rcv["udiDuplicates"] >= 1


def test_overwrite_of_unsent_and_unread_blocks(wd):
    """Retransmission faster than the radio polls: writes replace blocks not yet sent; reads
    slower than the radio: received blocks are overwritten before they are read."""
    data = pattern(5 * 122 + 1, seed=4)
    u = Uni(wd, data, timeout_ms=20, read_every=7, poll_scans=10)
    u.bench.step(3)
    assert u.send(limit=8000) == "done"
    assert u.sink.transfers == [data]
    sent_o = [t for t in u.radio.log if t.src == "O"]
    assert u.mo.writes > len(sent_o)          # some writes never went on air
    assert [n for n, _ in u.sink.records] == [1, 2, 3, 4, 5, FFFF]


def test_cyclic_reads_like_openplc_master(wd):
    """xReadValid always TRUE, the read block refreshed every 3 scans (OpenPLC's cyclic
    master): the same block is seen many times, and still nothing is delivered twice."""
    data = pattern(4 * 122, seed=5)
    u = Uni(wd, data, read_mode="cyclic", read_every=3, fate=drop_first("C", 1))
    u.bench.step(3)
    assert u.send() == "done"
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, FFFF]


def test_write_errors_are_retried(wd):
    data = pattern(2 * 122 + 3, seed=6)
    u = Uni(wd, data, timeout_ms=200)
    u.bench.step(3)
    u.port_o.write_fail = 2
    assert u.send() == "done"
    assert u.sink.transfers == [data]
    assert u.snd["udiWriteErrors"] == 2


def test_no_acknowledgement_gives_error_after_max_retries(wd):
    u = Uni(wd, pattern(300, seed=7), timeout_ms=100,
            fate=lambda src, block: "drop" if src == "O" and block[0] == 2 else "ok")
    u.snd["uMaxRetries"] = 3
    u.bench.step(3)
    assert u.send() == "error"
    assert u.snd["udiRetransmissions"] == 3
    assert u.sink.transfers == []


def test_error_id_visible_while_execute_high(wd):
    u = Uni(wd, pattern(300, seed=8), timeout_ms=100,
            fate=lambda src, block: "drop" if src == "O" and block[0] == 1 else "ok")
    u.snd["uMaxRetries"] = 2
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["xError"], 3000)
    assert u.snd["eErrorId"] == E_NO_ACK
    assert not u.snd["xBusy"] and not u.snd["xDone"]
    u.bench.step(5)
    assert u.snd["xError"]                     # held while xExecute stays TRUE
    u.snd["xExecute"] = False
    u.bench.step(2)
    assert not u.snd["xError"] and u.snd["eErrorId"] == E_NONE


def test_single_chunk_transfer_ends_with_an_empty_last_record_that_is_not_delivered(wd):
    """P5: one chunk goes as record 1 and an empty 16#FFFF. The receiver delivers record 1
    only: the empty 16#FFFF ends the transfer (xTransferEnd) without an xRecordValid, so a
    store or a kit's records see no empty record (issue 39)."""
    data = pattern(40, seed=9)
    u = Uni(wd, data)
    u.bench.step(3)
    assert u.send() == "done"
    assert [(n, len(p)) for n, p in u.sink.records] == [(1, 40)]
    assert u.sink.transfers == [data]
    assert (u.rcv["udiRecords"], u.rcv["udiTransfers"], u.rcv["wAck"]) == (1, 1, FFFF)


def test_consecutive_transfers_restart_at_one(wd):
    u = Uni(wd, pattern(200, seed=10))
    u.bench.step(3)
    assert u.send() == "done"
    u.src.data = pattern(300, seed=11)
    assert u.send() == "done"
    assert u.sink.transfers == [pattern(200, seed=10), pattern(300, seed=11)]
    assert [n for n, _ in u.sink.records] == [1, FFFF, 1, 2, FFFF]
    assert u.rcv["udiTransfers"] == 2 and u.snd["udiTransfers"] == 2
    # only the first transfer after the start opened with the reset record; the second
    # needed none: the receiver had closed the first
    o_nums = [t.block[0] for t in u.radio.log if t.src == "O"]
    assert 0 not in o_nums[o_nums.index(1):]


def test_ack_by_caller_holds_the_acknowledgement(wd):
    data = pattern(2 * 122 + 5, seed=12)
    u = Uni(wd, data)
    u.sink.pulse = False
    u.rcv["xAckByCaller"] = True
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.rcv["xRecordValid"], 500)
    assert u.rcv["wRecordNumber"] == 1
    u.bench.step(60)                     # the caller takes its time
    assert u.rcv["xRecordValid"] and u.rcv["wAck"] == 0
    assert u.mc.write_area[0] == 0 and u.snd["wRecord"] == 1
    u.rcv["xRecordProcessed"] = True
    assert u.bench.run_until(lambda: not u.rcv["xRecordValid"], 5)
    assert u.rcv["wAck"] == 1
    # from now on the caller acknowledges every record at once
    def auto(u=u):
        u.rcv["xRecordProcessed"] = u.rcv["xRecordValid"]
    u.bench.parts.append(type("Auto", (), {"before_scan": lambda self: auto()})())
    assert u.bench.run_until(lambda: u.snd["xDone"], 3000)
    assert [n for n, _ in u.sink.records] == [1, 2, FFFF]
    assert u.sink.transfers == [data]


# ---------------------------------------------------------------- restarts

def restarted_after(wd, old, records, new):
    """A transfer of `old` whose outstation PLC restarts once the receiver has `records`
    records; the new sender's data is `new`."""
    u = Uni(wd, old)
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.rcv["udiRecords"] >= records, 2000)
    u.restart_outstation()
    u.src.data = new
    return u


def test_sender_restart_mid_transfer(wd):
    """The outstation PLC restarts after 2 of 5 records: the new sender starts with record 1
    at once (no reset record); the receiver takes record 1 as a new transfer (P18), reports
    the open one failed; the new transfer arrives whole."""
    old, new = pattern(5 * 122, seed=13), pattern(3 * 122, seed=14)
    u = restarted_after(wd, old, 2, new)
    u.bench.step(5)
    assert u.send() == "done"
    assert u.rcv["udiFailedTransfers"] == 1
    assert u.rcv["eLastErrorId"] == E_SENDER_RESET
    assert u.sink.transfers == [new]
    assert not any(t.src == "O" and t.block[0] == 0 for t in u.radio.log)


def test_sender_restart_first_record_lost(wd):
    """The first record 1 after the restart is lost for good: it is sent again, the receiver
    still takes it as a new transfer."""
    old, new = pattern(6 * 122, seed=15), pattern(2 * 122, seed=16)
    u = restarted_after(wd, old, 3, new)
    u.radio.fate = drop_first("O", 1)
    u.bench.step(5)
    assert u.send() == "done"
    assert u.rcv["udiFailedTransfers"] == 1
    assert u.sink.transfers == [new]


def test_receiver_restart_mid_transfer(wd):
    """The central PLC restarts after 2 records: it acknowledges 0, the sender reports
    MIP_ERR_PEER_RESET; sent again, the transfer arrives once, whole."""
    data = pattern(5 * 122, seed=17)
    u = Uni(wd, data)
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.rcv["udiRecords"] >= 2, 2000)
    u.restart_central()
    assert u.bench.run_until(lambda: u.snd["xError"], 2000)
    assert u.snd["eErrorId"] == E_PEER_RESET
    assert not u.snd["xAborted"]       # a failure, not an abort
    u.snd["xExecute"] = False
    u.bench.step(2)
    u.sink.records.clear()
    assert u.send() == "done"
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, 4, FFFF]


def test_abort_then_new_transfer(wd):
    old, new = pattern(5 * 122, seed=18), pattern(150, seed=19)
    u = Uni(wd, old)
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.rcv["udiRecords"] >= 2, 2000)
    u.snd["xAbort"] = True
    u.bench.step()
    assert u.snd["xError"] and u.snd["eErrorId"] == E_ABORTED
    assert u.snd["xAborted"]           # beside xError (the CODESYS behaviour model's output)
    u.snd["xAbort"] = False
    u.snd["xExecute"] = False
    u.bench.step(3)
    u.src.data = new
    assert u.send() == "done"
    assert u.rcv["udiFailedTransfers"] == 1
    assert u.sink.transfers == [new]


def test_receiver_transfer_timeout(wd):
    """The sender goes silent mid-transfer: after tTransferTimeout the receiver fails the
    transfer and acknowledges 0; a sender that comes back then gets MIP_ERR_PEER_RESET."""
    u = Uni(wd, pattern(5 * 122, seed=20), transfer_timeout_ms=2000)
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.rcv["udiRecords"] >= 2, 2000)
    u.radio.fate = lambda src, block: "drop" if src == "O" else "ok"
    t0 = u.plc_c.time_ns
    assert u.bench.run_until(lambda: u.rcv["xError"], 1000)
    assert u.rcv["eErrorId"] == E_TRANSFER_TIMEOUT
    assert u.plc_c.time_ns - t0 >= 2000 * MS
    assert u.rcv["wAck"] == 0
    u.radio.fate = lambda src, block: "ok"
    assert u.bench.run_until(lambda: u.snd["xError"], 2000)
    assert u.snd["eErrorId"] == E_PEER_RESET
    assert u.sink.transfers == []


# ---------------------------------------------------------------- numbers the note leaves open

class ScriptedReceiver:
    """Play the sender by hand: put a record into the central modem's read area."""

    def __init__(self, u):
        self.u = u

    def feed(self, number, payload=(), scans=4):
        self.u.mc.receive([number] + list(payload))
        self.u.bench.step(scans)


def test_receiver_classifies_numbers(wd):
    u = Uni(wd, [], timeout_ms=200)
    r, sr = u.rcv, ScriptedReceiver(u)
    u.bench.step(3)
    sr.feed(1, [11])
    sr.feed(2, [22])
    assert r["wAck"] == 2
    sr.feed(7, [77])                     # unexpected: ignored, still acknowledging 2
    assert r["wAck"] == 2 and r["udiUnexpected"] == 1
    u.bench.step(20)
    assert u.mc.write_area[0] == 2       # acknowledged again
    sr.feed(3, [33])
    sr.feed(3, [33])                     # duplicate: discarded
    assert r["udiDuplicates"] == 1
    sr.feed(FFFF, [44])
    assert r["xTransferComplete"] and r["wAck"] == FFFF
    sr.feed(FFFF, [44])
    assert r["udiDuplicates"] == 2
    assert u.sink.records == [(1, [11]), (2, [22]), (3, [33]), (FFFF, [44])]
    assert u.sink.transfers == [[11, 22, 33, 44]]
    sr.feed(2, [1])                      # after a complete transfer only 1 may follow
    assert r["udiUnexpected"] == 2 and r["xTransferComplete"]
    sr.feed(1, [5])
    sr.feed(2, [6])
    assert r["xBusy"]
    sr.feed(0)                           # the sender's reset record: transfer failed
    assert r["xError"] and r["eErrorId"] == E_SENDER_RESET and r["wAck"] == 0
    assert r["udiFailedTransfers"] == 1
    sr.feed(1, [7])
    sr.feed(2, [8])
    sr.feed(3, [9])
    assert not r["xError"] and r["xBusy"]
    sr.feed(1, [10], scans=1)            # sender restarted: old transfer failed, new one starts
    u.bench.step(3)
    assert r["udiFailedTransfers"] == 2 and r["eLastErrorId"] == E_SENDER_RESET
    assert u.sink.records[-1] == (1, [10]) and r["wAck"] == 1
    sr.feed(0x8000, [1])                 # far ahead: ignored
    assert r["wAck"] == 1 and r["udiUnexpected"] == 3


def test_receiver_ignores_stale_last_record_after_restart(wd):
    """A restarted receiver reading the previous transfer's 16#FFFF must not deliver it."""
    u = Uni(wd, [], timeout_ms=200)
    u.mc.receive([FFFF, 1, 2, 3])
    u.bench.step(10)
    assert u.sink.records == [] and u.rcv["udiUnexpected"] == 1 and u.rcv["wAck"] == 0


def test_sender_counts_unexpected_acknowledgements(wd):
    data = pattern(2 * 122, seed=21)
    u = Uni(wd, data, timeout_ms=200, fate=lambda src, block: "drop" if src == "O" else "ok")
    u.bench.step(3)
    u.mo.receive([0])                               # receiver idle: acknowledges 0
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["eState"] == S_WAIT_ACK, 200)
    u.bench.step(3)
    u.mo.receive([9])                               # nonsense acknowledgement
    u.bench.step(3)
    assert u.snd["udiUnexpectedAcks"] == 1 and u.snd["wRecord"] == 1
    u.mo.receive([1])
    assert u.bench.run_until(lambda: u.snd["wRecord"] == FFFF, 100)


def jump_counters(u, to):
    """White box: after record 1, while the sender waits for chunk 2, set both sides as if
    record `to` had just been acknowledged."""
    u.src.hold_from = 1
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["eState"] == S_GET_CHUNK and u.snd["udiRecords"] == 1
                             and u.snd["xChunkRequest"], 2000)
    u.snd["wRecord"] = to
    u.snd["wPrevAck"] = to
    u.rcv["wL"] = to
    u.mc.read_area[0] = to          # the last record the central received
    u.mo.read_area[0] = to          # and its acknowledgement at the outstation
    u.src.hold_from = None


def test_more_than_65534_records(wd):
    """Jump the counters (white box) to 65532, then offer further chunks: record 65534 is the
    last ordinary number; another non-last chunk fails the transfer with
    MIP_ERR_TOO_MANY_RECORDS, and the receiver reports that transfer failed when the next
    transfer's record 1 arrives (P18). (Counting 65534 real records would take hours of virtual radio.)"""
    u = Uni(wd, pattern(10 * 122, seed=22))
    jump_counters(u, 65532)
    assert u.bench.run_until(lambda: u.snd["xError"], 3000)
    assert u.snd["eErrorId"] == E_TOO_MANY
    assert [n for n, _ in u.sink.records] == [1, 65533, 65534]
    assert u.rcv["wAck"] == 65534 and u.rcv["xBusy"]
    u.snd["xExecute"] = False
    u.bench.step(2)
    u.src.data = pattern(100, seed=23)
    assert u.send() == "done"
    assert u.rcv["udiFailedTransfers"] == 1 and u.sink.transfers == [pattern(100, seed=23)]
    assert u.rcv["eLastErrorId"] == E_SENDER_RESET


def test_record_65535_after_65534(wd):
    u = Uni(wd, pattern(3 * 122, seed=24))
    jump_counters(u, 65533)
    assert u.bench.run_until(lambda: u.snd["xDone"], 3000)
    assert [n for n, _ in u.sink.records] == [1, 65534, FFFF]
    assert u.rcv["xTransferComplete"] and u.rcv["udiTransfers"] == 1


def test_record_one_again_with_other_content_is_a_new_transfer(wd):
    """A sender that restarts right after its first record sends record 1 again, with new
    content, before the receiver's acknowledgement of the old one reached it: the receiver
    tells it from a duplicate by content, reports the old transfer failed and delivers it."""
    u = Uni(wd, [], timeout_ms=200)
    r, sr = u.rcv, ScriptedReceiver(u)
    u.bench.step(3)
    sr.feed(1, [11, 12])
    sr.feed(1, [11, 12])                 # true duplicate
    assert r["udiDuplicates"] == 1 and r["udiFailedTransfers"] == 0
    sr.feed(1, [21, 22])                 # same number, other content
    assert r["udiFailedTransfers"] == 1 and r["eLastErrorId"] == E_SENDER_RESET
    assert u.sink.records == [(1, [11, 12]), (1, [21, 22])]
    sr.feed(2, [23])
    sr.feed(2, [99])                     # number 2 again with other content: unexpected
    assert r["udiUnexpected"] == 1 and r["wAck"] == 2
    sr.feed(FFFF, [24])
    assert u.sink.transfers == [[21, 22, 23, 24]]


# ---------------------------------------------------------------- a dead link (issue 38)

def test_a_dead_link_is_a_link_error_at_both_blocks_and_the_transfer_resumes(wd):
    """Reads of the own modem that keep failing (a serial line that cannot be opened, no
    answer) used to leave both blocks at error NONE, waiting without a word. They now show
    xLinkError with the runtime's reason and eWaitReason MIP_WAIT_LINK from the first failed
    read; the transfer is not failed by it and goes on when the reads succeed again."""
    data = pattern(5 * 122, seed=38)
    u = Uni(wd, data)
    u.bench.step(3)
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["udiRecords"] >= 2, 3000)
    u.port_o.read_fail = u.port_c.read_fail = 1110      # plcrt: no answer in time
    u.bench.step(6)
    for fb in (u.snd, u.rcv):
        assert fb["xLinkError"] and fb["wLinkError"] == 1110
        assert fb["eWaitReason"] == WAIT["MIP_WAIT_LINK"]
        assert not fb["xError"] and fb["eErrorId"] == E_NONE
    u.port_o.read_fail = u.port_c.read_fail = 0
    assert u.bench.run_until(lambda: u.snd["xDone"], 20000)
    assert u.sink.transfers == [data]
    for fb in (u.snd, u.rcv):
        assert not fb["xLinkError"] and fb["wLinkError"] == 1110   # the reason is kept


# ---------------------------------------------------------------- the enable-type outputs (issue 46)

def test_the_receiver_is_enable_type_valid_busy_and_a_transfer_that_completes(wd):
    """MIP_Receiver as st_lib/CONVENTIONS.md's enable-type block: xBusy from the first enabled
    call and through a completed transfer (its work has no end); xValid also needs a read of
    the own modem and drops while the reads fail; a completed transfer is xTransferEnd for
    one scan and xTransferComplete held; xEnable FALSE clears them all."""
    data = pattern(3 * 122, seed=46)
    u = Uni(wd, data, enable=False)
    u.bench.step(3)
    assert not (u.rcv["xBusy"] or u.rcv["xValid"] or u.rcv["xTransferComplete"])
    u.rcv["xEnable"] = True
    u.bench.step()
    assert u.rcv["xBusy"] and not u.rcv["xError"]
    assert u.bench.run_until(lambda: u.rcv["xValid"], 50)
    u.snd["xExecute"] = True
    ends = 0
    while not u.rcv["xTransferComplete"] and u.bench.scans < 5000:
        u.bench.step()
        ends += u.rcv["xTransferEnd"]
        assert u.rcv["xBusy"] and u.rcv["xValid"]
    assert u.rcv["xTransferComplete"] and ends == 1 and u.sink.transfers == [data]
    u.bench.step(20)
    assert u.rcv["xTransferComplete"] and u.rcv["xBusy"] and u.rcv["xValid"]
    assert not u.rcv["xTransferEnd"]
    u.port_c.read_fail = 1110                            # plcrt: no answer in time
    u.bench.step(6)
    assert u.rcv["xLinkError"] and u.rcv["xBusy"] and not u.rcv["xValid"]
    assert not u.rcv["xError"]
    u.port_c.read_fail = 0
    assert u.bench.run_until(lambda: u.rcv["xValid"], 50)
    u.rcv["xEnable"] = False
    u.bench.step()
    assert not (u.rcv["xBusy"] or u.rcv["xValid"] or u.rcv["xTransferComplete"])
