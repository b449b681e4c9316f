"""The LGF-style `status : Word` output that the SCL generator (stc.scl_out) adds to the blocks
with xBusy / xError / eErrorId (MIP_Link: `sendStatus` and `recvStatus`, one per side), run on
the generated SCL (the output exists only there): 16#7000 idle, 16#7001 the first busy call,
16#7002 busy, 16#0000 done, 16#8000 + eErrorId failed (docs/wiring-s7.md, "The status
output")."""
from pathlib import Path

import pytest

from stlib_sim import ERR, Bi, Uni, pattern

IDLE, FIRST, BUSY, DONE = 0x7000, 0x7001, 0x7002, 0x0000


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PLCRT_STLIB_DIALECT", "scl")     # the bench builds from the generated SCL
        yield tmp_path_factory.mktemp("scl_status")


def expected(fb, busy_before, side=""):
    if fb[f"x{side}Error"]:
        return 0x8000 | fb[f"e{side}ErrorId"]
    if fb[f"x{side}Busy"]:
        return BUSY if busy_before else FIRST
    if fb.has(f"x{side}Done") and fb[f"x{side}Done"]:   # an enable-type side has no xDone
        return DONE
    return IDLE


def watch(u, fb, scans, until=None, side="", status="status"):
    """Step scan by scan; every scan the status is what xBusy/xError/xDone/eErrorId say (of
    the side `side` of a combined block: its output `status`). Returns the statuses seen, in
    order, without repeats."""
    seen, busy_before = [], False
    for _ in range(scans):
        u.bench.step()
        want = expected(fb, busy_before, side)
        assert fb[status] == want, (status, hex(fb[status]), hex(want))
        if not seen or seen[-1] != want:
            seen.append(want)
        busy_before = bool(fb[f"x{side}Busy"])
        if until is not None and until():
            break
    return seen


def test_sender_status_idle_first_busy_done(wd):
    u = Uni(wd, pattern(300, seed=5))
    assert u.snd["status"] == IDLE
    u.snd["xExecute"] = True
    seen = watch(u, u.snd, 3000, until=lambda: u.snd["xDone"])
    assert u.snd["xDone"]
    assert seen == [FIRST, BUSY, DONE]
    u.snd["xExecute"] = False
    assert watch(u, u.snd, 2) == [IDLE]


def test_sender_status_names_the_error(wd):
    u = Uni(wd, pattern(10, seed=6), chunk=0)       # uChunkSize 0: MIP_ERR_CHUNK_SIZE
    u.snd["xExecute"] = True
    watch(u, u.snd, 5, until=lambda: u.snd["xError"])
    assert u.snd["xError"]
    assert u.snd["status"] == 0x8000 | ERR["MIP_ERR_CHUNK_SIZE"]


def test_receiver_status_follows_its_enable(wd):
    """An enable-type block: busy from the first enabled call, and still busy after a
    completed transfer (no 16#0000: its work has no end); idle again with xEnable FALSE."""
    u = Uni(wd, pattern(200, seed=7), enable=False)
    assert u.rcv["status"] == IDLE
    u.rcv["xEnable"] = True
    u.snd["xExecute"] = True
    seen = watch(u, u.rcv, 3000, until=lambda: u.rcv["xTransferComplete"])
    assert u.rcv["xTransferComplete"] and seen == [FIRST, BUSY]
    u.rcv["xEnable"] = False
    assert watch(u, u.rcv, 2) == [IDLE]


def test_link_has_a_status_word_per_side(wd):
    """MIP_Link: sendStatus follows the sending side (execute-type: first, busy, done),
    recvStatus the receiving side (enable-type: first, busy while enabled)."""
    data = pattern(150, seed=8)
    b = Bi(wd, data_o=data)                              # both sides enabled, none executing
    for fb in (b.lo, b.lc):
        assert fb["sendStatus"] == IDLE and fb["recvStatus"] == IDLE
    assert watch(b, b.lc, 3, side="Recv", status="recvStatus") == [FIRST, BUSY]
    assert b.lc["sendStatus"] == IDLE
    b.lo["xExecute"] = True
    seen = watch(b, b.lo, 8000, until=lambda: b.lo["xSendDone"], side="Send",
                 status="sendStatus")
    assert b.lo["xSendDone"] and seen == [FIRST, BUSY, DONE]
    assert b.sink_c.transfers == [data] and b.lc["recvStatus"] == BUSY
