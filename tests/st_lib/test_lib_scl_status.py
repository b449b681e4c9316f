"""The LGF-style `status : Word` output that the SCL generator (stc.scl_out) adds to the blocks
with xBusy / xError / eErrorId, run on the generated SCL (the output exists only there):
16#7000 idle, 16#7001 the first busy call, 16#7002 busy, 16#0000 done, 16#8000 + eErrorId
failed (docs/wiring-s7.md, "The status output")."""
from pathlib import Path

import pytest

from stlib_sim import ERR, Uni, pattern

IDLE, FIRST, BUSY, DONE = 0x7000, 0x7001, 0x7002, 0x0000


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PLCRT_STLIB_DIALECT", "scl")     # the bench builds from the generated SCL
        yield tmp_path_factory.mktemp("scl_status")


def expected(fb, busy_before):
    if fb["xError"]:
        return 0x8000 | fb["eErrorId"]
    if fb["xBusy"]:
        return BUSY if busy_before else FIRST
    if fb["xDone"]:
        return DONE
    return IDLE


def watch(u, fb, scans, until=None):
    """Step scan by scan; every scan the status is what xBusy/xError/xDone/eErrorId say.
    Returns the statuses seen, in order, without repeats."""
    seen, busy_before = [], False
    for _ in range(scans):
        u.bench.step()
        want = expected(fb, busy_before)
        assert fb["status"] == want, (hex(fb["status"]), hex(want))
        if not seen or seen[-1] != want:
            seen.append(want)
        busy_before = bool(fb["xBusy"])
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
    u = Uni(wd, pattern(200, seed=7), enable=False)
    assert u.rcv["status"] == IDLE
    u.rcv["xEnable"] = True
    u.snd["xExecute"] = True
    seen = watch(u, u.rcv, 3000, until=lambda: u.rcv["xDone"])
    assert seen[:2] == [FIRST, BUSY] and seen[-1] == DONE
