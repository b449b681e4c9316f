"""Layouts and modes: bidirectional MIP_Link, static mode, polled drive under faults, chunk-size
limits, the in-memory MIP_BufferSender."""
import random
from pathlib import Path

import pytest

from stlib_sim import ERR, FFFF, Bi, Uni, pattern

E_NONE, E_CHUNK_SIZE, E_CHUNK_LEN, E_NO_ACK, E_PEER_RESET, E_TOO_MANY, E_ABORTED, \
    E_SENDER_RESET, E_TRANSFER_TIMEOUT, E_BUFFER_LEN = (
        ERR["MIP_ERR_" + n] for n in ("NONE", "CHUNK_SIZE", "CHUNK_LEN", "NO_ACK", "PEER_RESET",
                                      "TOO_MANY_RECORDS", "ABORTED", "SENDER_RESET",
                                      "TRANSFER_TIMEOUT", "BUFFER_LEN"))


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_modes")


# ---------------------------------------------------------------- bidirectional (note 2.2)

def test_bidirectional_transfers_at_the_same_time(wd):
    a, b = pattern(5 * 121 + 17, seed=31), pattern(3 * 121 + 2, seed=32)
    bi = Bi(wd, a, b)
    bi.bench.step(3)
    assert bi.send_both() == ["done", "done"]
    assert bi.sink_c.transfers == [a]          # outstation -> central
    assert bi.sink_o.transfers == [b]          # central -> outstation
    # register 0 carries the outstation's records and the central's acknowledgements,
    # register 1 the central's records and the outstation's acknowledgements
    o_rec = [t.block[0] for t in bi.radio.log if t.src == "O" and t.block[0] not in (0,)]
    c_rec = [t.block[1] for t in bi.radio.log if t.src == "C" and t.block[1] not in (0,)]
    assert [n for n in dict.fromkeys(o_rec)] == [1, 2, 3, 4, 5, FFFF]
    assert [n for n in dict.fromkeys(c_rec)] == [1, 2, 3, FFFF]
    assert all(len(t.block) <= 123 and len(t.block) >= 2 for t in bi.radio.log)


def test_bidirectional_with_losses_and_duplicates(wd):
    rnd = random.Random(33)

    def fate(src, block):
        return rnd.choices(["ok", "lost", "dup", "drop"], [6, 1, 1, 1])[0]
    a, b = pattern(4 * 121, seed=34), pattern(6 * 121 + 1, seed=35)
    bi = Bi(wd, a, b, fate=fate, timeout_ms=250)
    bi.bench.step(3)
    assert bi.send_both(limit=20000) == ["done", "done"]
    assert bi.sink_c.transfers == [a] and bi.sink_o.transfers == [b]


def test_bidirectional_polled(wd):
    a, b = pattern(2 * 121, seed=36), pattern(3 * 121, seed=37)
    bi = Bi(wd, a, b, polled=True, timeout_ms=400, fate=None)
    bi.bench.step(3)
    assert bi.send_both() == ["done", "done"]
    assert bi.sink_c.transfers == [a] and bi.sink_o.transfers == [b]


def test_bidirectional_one_way_only_and_idle_link_falls_silent(wd):
    a = pattern(3 * 121, seed=38)
    bi = Bi(wd, a, [])
    bi.bench.step(3)
    bi.lo["xExecute"] = True
    assert bi.bench.run_until(lambda: bi.lo["xSendDone"], 5000)
    assert bi.sink_c.transfers == [a] and bi.sink_o.transfers == []
    bi.bench.step(100)
    n = len(bi.radio.log)
    bi.bench.step(500)                       # 5 s idle: no more telegrams
    assert len(bi.radio.log) == n


def test_bidirectional_chunk_size_needs_two_counters(wd):
    bi = Bi(wd, [1, 2, 3], [], chunk=2)
    bi.bench.step(3)
    bi.lo["xExecute"] = True
    bi.bench.step(3)
    assert bi.lo["xSendError"] and bi.lo["eSendErrorId"] == E_CHUNK_SIZE


# ---------------------------------------------------------------- static mode

def test_static_mode_pads_the_last_record(wd):
    """Static mode: every block has the configured 123 registers; writes of unchanged content
    go nowhere, the link itself repeats unconfirmed blocks. The last record is padded with 0
    and the receiver reports the whole static block (122 payload registers)."""
    data = pattern(3 * 122 + 40, seed=41)
    u = Uni(wd, data, static_n=123, timeout_ms=300,
            fate=lambda src, block, r=random.Random(42): r.choice(["ok", "ok", "lost", "dup"]))
    u.bench.step(3)
    assert u.send(limit=8000) == "done"
    assert [n for n, _ in u.sink.records] == [1, 2, 3, FFFF]
    assert all(len(p) == 122 for _, p in u.sink.records)
    assert u.sink.transfers == [data + [0] * (4 * 122 - len(data))]
    assert all(len(t.block) == 123 for t in u.radio.log)


def test_static_mode_polled_setting_is_spontaneous(wd):
    data = pattern(2 * 122, seed=43)
    u = Uni(wd, data, static_n=123, polled=True)
    u.bench.step(3)
    assert u.send() == "done"
    assert u.sink.transfers == [data]


def test_static_mode_bidirectional(wd):
    a, b = pattern(2 * 121, seed=44), pattern(121 + 5, seed=45)
    bi = Bi(wd, a, b, static_n=123)
    bi.bench.step(3)
    assert bi.send_both() == ["done", "done"]
    assert bi.sink_c.transfers == [a]
    assert bi.sink_o.transfers == [b + [0] * (2 * 121 - len(b))]


# ---------------------------------------------------------------- polled drive under faults

def test_polled_with_losses(wd):
    rnd = random.Random(46)
    data = pattern(6 * 122 + 3, seed=47)
    u = Uni(wd, data, polled=True, timeout_ms=300,
            fate=lambda src, block: rnd.choices(["ok", "lost", "dup", "drop"], [5, 1, 1, 1])[0])
    u.bench.step(3)
    assert u.send(limit=20000) == "done"
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, 4, 5, 6, FFFF]


# ---------------------------------------------------------------- chunk sizes

@pytest.mark.parametrize("chunk,ok", [(0, False), (1, False), (2, True), (60, True),
                                      (123, True), (124, False), (127, False), (148, False)])
def test_chunk_size_limits(wd, chunk, ok):
    data = pattern(7, seed=48)
    u = Uni(wd, data, chunk=chunk)
    u.bench.step(3)
    res = u.send()
    if ok:
        assert res == "done" and u.sink.transfers == [data]
        assert max(len(b) for b in u.port_o.writes) <= chunk
    else:
        assert res == "error" and u.port_o.writes == []
        u.snd["xExecute"] = True
        u.bench.step(2)
        assert u.snd["eErrorId"] == E_CHUNK_SIZE


def test_chunk_longer_than_payload_room_is_an_error(wd):
    u = Uni(wd, pattern(50, seed=49), chunk=20)
    u.bench.step(3)
    u.src.before_scan_orig = u.src.before_scan

    def too_long():
        u.src.before_scan_orig()
        if u.snd["xChunkRequest"]:
            u.snd["uChunkLen"] = 20            # room is 19
    u.src.before_scan = too_long
    u.snd["xExecute"] = True
    assert u.bench.run_until(lambda: u.snd["xError"], 500)
    assert u.snd["eErrorId"] == E_CHUNK_LEN


def test_every_write_is_at_most_123_registers(wd):
    data = pattern(1000, seed=50)
    u = Uni(wd, data)
    u.bench.step(3)
    assert u.send(limit=10000) == "done"
    assert max(len(b) for b in u.port_o.writes) == 123
    assert u.sink.transfers == [data]


# ---------------------------------------------------------------- in-memory buffer

def buffer_pattern(n, seed):
    return [(i * 7 + seed) & 0xFFFF for i in range(n)]


@pytest.mark.parametrize("length", [1, 122, 123, 1000, 8192])
def test_buffer_sender(wd, length):
    u = Uni(wd, buffer=True)
    u.plc_o["MAIN.bs_seed"] = 5
    u.plc_o["MAIN.bs_fill"] = True
    u.bench.step(1)
    u.plc_o["MAIN.bs_fill"] = False
    u.snd["udiLength"] = length
    assert u.send(limit=40000) == "done"
    assert u.sink.transfers == [buffer_pattern(length, 5)]


def test_buffer_sender_empty_and_too_long(wd):
    u = Uni(wd, buffer=True)
    u.snd["udiLength"] = 0
    u.bench.step(2)
    assert u.send() == "done"
    # an empty transfer: records 1 and 16#FFFF without data, none delivered; it completes
    assert u.sink.records == [] and u.sink.transfers == [[]]
    u.snd["udiLength"] = 8193
    u.snd["xExecute"] = True
    u.bench.step(3)
    assert u.snd["xError"] and u.snd["eErrorId"] == E_BUFFER_LEN
    assert not u.snd["xBusy"]


def test_static_mode_with_cyclic_io_like_openplc(wd):
    """Static mode wired to a cyclic master (OpenPLC): the write image goes out every cycle,
    done is a timer, reads are continuous. Equal content is not re-sent by the modem."""
    from stlib_sim import CyclicPort
    data = pattern(4 * 122 + 9, seed=51)
    u = Uni(wd, data, static_n=123, timeout_ms=500,
            fate=lambda src, block, r=random.Random(52): r.choice(["ok", "ok", "lost", "dup"]))
    for attr, fb, modem in (("port_o", u.snd, u.mo), ("port_c", u.rcv, u.mc)):
        new = CyclicPort(fb, modem)
        u.bench.parts[u.bench.parts.index(getattr(u, attr))] = new
        setattr(u, attr, new)
    u.bench.step(3)
    assert u.send(limit=10000) == "done"
    assert u.sink.transfers == [data + [0] * (5 * 122 - len(data))]
    sent_o = [t for t in u.radio.log if t.src == "O"]
    assert len(u.port_o.writes) > 2 * len(sent_o)
    # equal content is not sent again once the link confirmed it
    for prev, nxt in zip(sent_o, sent_o[1:]):
        assert not (prev.fate in ("ok", "drop") and prev.block == nxt.block)


def test_bidirectional_abort_and_send_again(wd):
    """The outstation aborts its transfer mid-way while the central keeps sending: the
    central's receiving side reports the open transfer failed when the outstation resets it,
    the outstation's next transfer arrives whole, and the central's transfer is unaffected."""
    old, new, b = pattern(5 * 121, seed=53), pattern(2 * 121 + 3, seed=54), pattern(4 * 121, seed=55)
    bi = Bi(wd, old, b)
    bi.bench.step(3)
    bi.lo["xExecute"] = True
    bi.lc["xExecute"] = True
    assert bi.bench.run_until(lambda: bi.lc["udiRecordsReceived"] >= 2, 3000)
    bi.lo["xAbort"] = True
    bi.bench.step()
    assert bi.lo["xSendError"] and bi.lo["eSendErrorId"] == E_ABORTED
    bi.lo["xAbort"] = False
    bi.lo["xExecute"] = False
    bi.bench.step(2)
    bi.src_o.data = new
    bi.lo["xExecute"] = True
    assert bi.bench.run_until(lambda: bi.lo["xSendDone"] and bi.lc["xSendDone"], 8000)
    assert bi.sink_c.transfers == [new]
    assert bi.sink_o.transfers == [b]
    assert bi.lc["xRecvTransferComplete"] and bi.lc["xRecvValid"] and not bi.lc["xRecvError"]
    # the aborted transfer was reported by the central's receiving side
    assert bi.lc["udiFailedTransfers"] == 1
