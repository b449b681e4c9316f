"""The full number space, counted for real (no white-box jumps): the test plays the other side
as fast as the handshakes allow (a few scans per record, one payload register per record)."""
from pathlib import Path

import pytest

from stlib_sim import ALL, ERR, FFFF, Fb, build

E_TOO_MANY = ERR["MIP_ERR_TOO_MANY_RECORDS"]


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_count")


def run_sender(wd, n_chunks):
    """MIP_Sender with chunk size 2 sends n_chunks chunks (the last flagged last); the test
    acknowledges every record at once. Returns (numbers written, sender)."""
    plc = build(ALL, wd)
    snd = Fb(plc, "snd")
    snd["uChunkSize"] = 2
    snd["tTimeout"] = 100_000_000          # 100 ms
    P = plc.__setitem__
    G = plc.__getitem__
    P("MAIN.snd_r1", 1)                     # count 1: the receiver acknowledged 0 so far
    P("MAIN.snd.xReadValid", True)
    snd["xExecute"] = True
    numbers = []
    done_set = chunk_valid = False
    for _ in range(6 * n_chunks + 100):
        plc.scan()
        if G("MAIN.snd.xDone") or G("MAIN.snd.xError"):
            break
        if G("MAIN.snd.xChunkRequest"):
            k = G("MAIN.snd.udiChunkIndex")
            P("MAIN.snd_c0", k & 0xFFFF)
            P("MAIN.snd.uChunkLen", 1)
            P("MAIN.snd.xChunkLast", k == n_chunks - 1)
            P("MAIN.snd.xChunkValid", True)
            chunk_valid = True
        elif chunk_valid:
            P("MAIN.snd.xChunkValid", False)
            chunk_valid = False
        req = G("MAIN.snd.xWriteReq")
        if req and not done_set:
            numbers.append(G("MAIN.snd_w0"))
            P("MAIN.snd.xWriteDone", True)
            done_set = True
        elif not req and done_set:
            P("MAIN.snd.xWriteDone", False)
            done_set = False
            P("MAIN.snd_r2", numbers[-1])    # the receiver acknowledges what was written
    return numbers, snd


def test_sender_counts_to_65534_then_65535(wd):
    numbers, snd = run_sender(wd, 65535)
    assert snd["xDone"]
    assert numbers == list(range(1, 65535)) + [FFFF]   # record 1 first: no reset record
    assert snd["udiRecords"] == 65535 and snd["udiRetransmissions"] == 0


def test_sender_refuses_a_65535th_ordinary_record(wd):
    numbers, snd = run_sender(wd, 65536)
    assert snd["xError"] and snd["eErrorId"] == E_TOO_MANY
    assert numbers == list(range(1, 65535))


def test_receiver_accepts_the_full_number_space(wd):
    """The test plays the sender: records 1..65534 and 16#FFFF, each payload = its number;
    every record is delivered once, in order, and acknowledged."""
    plc = build(ALL, wd)
    P, G = plc.__setitem__, plc.__getitem__
    P("MAIN.rcv.xEnable", True)
    P("MAIN.rcv_r1", 2)                       # count: number + 1 payload register
    delivered = 0
    offset_ok = True
    done_set = False
    numbers = list(range(1, 65535)) + [FFFF]
    i = 0
    P("MAIN.rcv_r2", numbers[0])
    P("MAIN.rcv_r3", numbers[0])
    P("MAIN.rcv.xReadValid", True)
    for _ in range(5 * len(numbers) + 50):
        plc.scan()
        if G("MAIN.rcv.xRecordValid"):
            assert G("MAIN.rcv.wRecordNumber") == numbers[i] and G("MAIN.rcv_p0") == numbers[i]
            offset_ok &= G("MAIN.rcv.udiRecordOffset") == i
            delivered += 1
        req = G("MAIN.rcv.xWriteReq")
        if req and not done_set:
            ack = G("MAIN.rcv_w0")
            P("MAIN.rcv.xWriteDone", True)
            done_set = True
            if ack == numbers[i]:
                i += 1
                if i == len(numbers):
                    break
                P("MAIN.rcv_r2", numbers[i])  # the next record arrives
                P("MAIN.rcv_r3", numbers[i])
        elif not req and done_set:
            P("MAIN.rcv.xWriteDone", False)
            done_set = False
    plc.scan(3)
    assert delivered == 65535 and i == 65535 and offset_ok
    assert G("MAIN.rcv.xTransferComplete") and G("MAIN.rcv.wAck") == FFFF
    assert G("MAIN.rcv.udiDuplicates") == 0 and G("MAIN.rcv.udiUnexpected") == 0
