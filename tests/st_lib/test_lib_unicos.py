"""MIP_UnicosEvents against the independent WinCC OA stand-in (peers/mippeer/unicos.py): what the
stand-in decodes is the relay entries given, the table's timing rules, the 253-byte bound,
retries and named errors for an exception or no answer, the fail-over of a redundant pair, and
the record reported processed (so acknowledged over the radio) only after the active driver's
positive response."""
import random

import pytest

from mippeer.unicos import UnicosConfig
from unicos_bench import UERR, USTATE, WAIT, UnicosBench, entry

T0 = 1767225600000          # 2026-01-01 00:00:00 UTC in ms


def relay_entries(n, seed=1, t0=T0):
    rnd = random.Random(seed)
    t = t0
    out = []
    for _ in range(n):
        t += rnd.randrange(0, 5000)
        out.append((rnd.randrange(0x100, 0x1000), rnd.randrange(1, 65536), 0x0101,
                    rnd.randrange(65536), t))
    return out


def record(entries):
    return sum((entry(*e) for e in entries), [])


def expected(entries, events32=True):
    return [(a, (tb << 16 | v) if events32 else v, ts // 10) for tb, a, _c, v, ts in entries]


def got(driver):
    return [(e["offset"], e["value"], e["ts_10ms"]) for e in driver.events]


@pytest.fixture
def wd(tmp_path_factory):
    return tmp_path_factory.getbasetemp() / "unicos_build"


@pytest.mark.parametrize("events32,little", [(True, False), (False, False), (True, True)],
                         ids=["32bit", "16bit", "32bit-little-endian-register"])
def test_the_driver_decodes_the_entries_given(wd, events32, little):
    cfg = UnicosConfig(little_endian_register=little)
    b = UnicosBench(wd, cfg, xEvents32=events32, xLittleEndianRegister=little)
    sizes = [1, 15, 3, 0, 7]                 # entries per record; 15 = a full MIP record
    entries = relay_entries(sum(sizes))
    recs, k = [], 0
    for n in sizes:
        recs.append(entries[k:k + n])
        k += n
    b.offer(*[record(r) for r in recs])
    b.drain()
    assert got(b.da) == expected(entries, events32)
    assert {e["sub"] for e in b.da.events} == {0x11 if events32 else 0x12}
    assert b.u["udiRecords"] == len(sizes) and b.u["udiEvents"] == len(entries)
    assert b.u["udiFrames"] == len([n for n in sizes if n])     # one frame per record
    assert b.db.events == [] and b.cb.adus == []                 # no pair: driver B untouched
    assert not b.u["xError"]


def test_the_time_stamp_is_utc_in_10_ms_rounded_down(wd):
    b = UnicosBench(wd)
    b.offer(record([(0x0101, 7, 0x0101, 1, T0 + 19), (0x0101, 7, 0x0101, 0, T0 + 86_400_000 + 5)]))
    b.drain()
    assert [e["utc"] for e in b.da.events] == ["2026-01-01T00:00:00.010Z", "2026-01-02T00:00:00.000Z"]


def test_full_table_goes_at_once_the_rest_after_max_delay(wd):
    b = UnicosBench(wd, xSendPerRecord=False, uTableEvents=4, tMaxDelay=2000)
    entries = relay_entries(6, seed=2)
    b.offer(record(entries))
    b.step(3)
    assert got(b.da) == expected(entries[:4])            # full: sent in the first scans
    assert b.src.processed == []
    b.run_until(lambda: len(b.da.events) == 6, 400)
    last = b.ca.adus[-1]
    sent_at = b.scans
    # the rest went tMaxDelay (200 scans of 10 ms) after the table got them, not before
    assert 199 <= sent_at - 2 <= 203, sent_at
    assert len(b.ca.adus) == 2 and last[13:15] == bytes([0x11, 2])   # header: 16#11, 2 events
    b.step(2)
    assert len(b.src.processed) == 1 and b.src.processed[0] >= sent_at - 1


def test_frames_stay_within_253_bytes_and_a_bigger_table_is_refused(wd):
    b = UnicosBench(wd, xEvents32=False, uTableEvents=24)   # 1 + 24 * 5 = 121 registers
    entries = relay_entries(15, seed=3)
    b.offer(record(entries), record(relay_entries(15, seed=4)))
    b.drain()
    assert all(len(adu) - 7 <= 253 for adu in b.ca.adus)
    assert b.da.refused == 0 and len(b.da.events) == 30
    b2 = UnicosBench(wd, xEvents32=True, uTableEvents=21)   # 1 + 21 * 6 = 127 > 123
    b2.offer(record(entries))
    b2.step(20)
    assert b2.u["xError"] and b2.u["eErrorId"] == UERR["MIP_UNI_ERR_TABLE_SIZE"]
    assert b2.ca.adus == [] and b2.src.processed == []


def test_a_record_of_broken_entries_is_refused_not_sent(wd):
    b = UnicosBench(wd)
    b.offer(record(relay_entries(2))[:-3])
    b.step(20)
    assert b.u["eErrorId"] == UERR["MIP_UNI_ERR_RECORD_LEN"] and b.u["eState"] == USTATE["MIP_UNI_REFUSED"]
    assert b.ca.adus == [] and b.src.processed == []


def test_exception_answers_are_retried_then_named_then_delivered_once(wd):
    b = UnicosBench(wd, tRetry=100, uMaxRetries=3)
    b.da.fail_next(5, code=6)                      # 06: slave device busy
    entries = relay_entries(3, seed=5)
    b.offer(record(entries))
    b.run_until(lambda: b.u["xError"], 1000)
    assert b.u["eErrorId"] == UERR["MIP_UNI_ERR_EXCEPTION"] and b.u["wException"] == 6
    assert len(b.ca.adus) == 4 and b.src.processed == []      # 1 + uMaxRetries, not acknowledged
    b.drain()
    assert len(b.ca.adus) == 6 and not b.u["xError"]
    assert got(b.da) == expected(entries)                      # once, in order
    assert b.u["udiRetries"] == 5


def test_no_answer_is_a_named_error_and_nothing_is_acknowledged(wd):
    b = UnicosBench(wd, tRetry=100, uMaxRetries=2)
    b.ca.down = True
    entries = relay_entries(2, seed=6)
    b.offer(record(entries))
    b.run_until(lambda: b.u["xError"], 1000)
    assert b.u["eErrorId"] == UERR["MIP_UNI_ERR_NO_ANSWER"]
    b.step(300)                                  # it keeps trying, at most every tRetry
    assert b.src.processed == [] and b.u["xError"]
    tries = len(b.ca.adus)
    assert 3 < tries <= 3 + 300 // 30 + 1, tries  # each try: 20 scans timeout + 10 scans tRetry
    b.ca.down = False
    b.drain()
    assert got(b.da) == expected(entries) and not b.u["xError"]


def test_redundant_pair_both_get_it_the_active_decides(wd):
    b = UnicosBench(wd, xRedundant=True, tRetry=100, uMaxRetries=1)
    first = relay_entries(4, seed=7)
    b.offer(record(first))
    b.drain()
    assert got(b.da) == got(b.db) == expected(first)
    # driver A (active) goes down: B takes the frame, the record is not processed (A decides)
    b.ca.down = True
    second = relay_entries(2, seed=8, t0=T0 + 10**6)
    b.offer(record(second))
    b.run_until(lambda: b.u["xError"], 1000)
    assert b.u["eErrorId"] == UERR["MIP_UNI_ERR_NO_ANSWER"] and len(b.src.processed) == 1
    assert got(b.db) == expected(first + second)
    # fail-over to B: B confirmed the frame already, so the record is processed, nothing resent
    b.u["xActiveB"] = True
    writes_b = len(b.cb.adus)
    b.drain()
    assert len(b.src.processed) == 2 and not b.u["xError"] and len(b.cb.adus) == writes_b
    # with B active and A still down, records go on; A's frames are counted missed
    third = relay_entries(3, seed=9, t0=T0 + 2 * 10**6)
    b.offer(record(third[:1]), record(third[1:]))
    b.drain()
    assert got(b.db) == expected(first + second + third)   # each event once at B
    assert got(b.da) == expected(first)
    # counted when a newer frame replaces an unconfirmed one in A's channel
    assert b.u["udiPassiveMissed"] >= 1 and b.u["xPassiveError"]


def test_processed_only_after_the_active_drivers_positive_response(wd):
    b = UnicosBench(wd, tRetry=50, uMaxRetries=0)
    answered = []
    orig = b.da.handle

    def handle(adu):
        r = orig(adu)
        if r is not None and not r[7] & 0x80:
            answered.append(b.scans)
        return r
    b.da.handle = handle
    b.da.fail_next(2, code=4)
    b.offer(*[record(relay_entries(1, seed=s)) for s in range(5)])
    b.drain()
    assert len(answered) == 5 and len(b.src.processed) == 5
    for ok, done in zip(answered, b.src.processed):
        assert done >= ok


def test_a_record_larger_than_the_table_goes_in_frames_processed_after_the_last(wd):
    b = UnicosBench(wd, uTableEvents=4)
    entries = relay_entries(10, seed=10)
    b.offer(record(entries))
    b.drain()
    assert [adu[14] for adu in b.ca.adus] == [4, 4, 2]      # header low byte: events per frame
    assert got(b.da) == expected(entries) and b.u["udiFrames"] == 3
    assert len(b.src.processed) == 1 and b.src.processed[0] > b.scans - 5


def test_disabled_and_enabled_again_the_record_is_sent_again_not_lost(wd):
    b = UnicosBench(wd, tRetry=100)
    b.ca.down = True
    entries = relay_entries(2, seed=11)
    b.offer(record(entries))
    b.step(10)
    b.u["xEnable"] = False
    b.step(30)                                   # the write under way ends (no answer)
    assert b.u["eState"] == USTATE["MIP_UNI_DISABLED"] and not b.u["stRequestA.xWriteReq"]
    assert b.src.processed == []
    b.ca.down = False
    b.u["xEnable"] = True
    b.drain()
    assert got(b.da) == expected(entries)


def test_parameters_are_sampled_at_the_rising_edge_of_xenable(wd):
    """st_lib/CONVENTIONS.md "sampled": xRedundant set while enabled changes nothing; the next
    enable takes it. The diagnostics say what the block waits for."""
    b = UnicosBench(wd)
    b.step(2)
    assert b.u["xValid"] and b.u["xBusy"] and b.u["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_RECORD"]
    b.u["xRedundant"] = True                       # while enabled: not taken
    first = relay_entries(2, seed=21)
    b.offer(record(first))
    b.drain()
    assert got(b.da) == expected(first) and got(b.db) == [] and b.cb.adus == []
    b.u["xEnable"] = False
    b.step(2)
    assert not b.u["xValid"] and not b.u["xBusy"]
    assert b.u["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_NONE"]
    b.u["xEnable"] = True                          # the rising edge takes xRedundant
    second = relay_entries(2, seed=22, t0=T0 + 10**6)
    b.offer(record(second))
    b.drain()
    assert got(b.da) == expected(first + second) and got(b.db) == expected(second)
