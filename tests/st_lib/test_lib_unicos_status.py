"""MIP_UnicosStatus against the independent WinCC OA stand-in: the table goes whole once, then on
a change, never twice within 50 ms; a pair gets it twice over; a driver that refuses is retried
with the newest table and named."""
from unicos_bench import SSTATE, UERR, WAIT, StatusBench


def test_sent_once_then_on_change_whole(tmp_path_factory):
    b = StatusBench(tmp_path_factory.getbasetemp() / "unicos_build", wOffset=100)
    t = list(range(1000, 1096))
    b.set_table(t)
    b.step(10)
    assert b.da.status == {(1, 100): t} and b.da.frames == 1
    assert b.s["xCurrent"] and b.s["udiTables"] == 1
    b.step(50)
    assert b.da.frames == 1                         # no change: nothing sent
    t[95] = 7
    b.set_table(t)
    b.step(2)
    assert b.da.status[(1, 100)] == t and b.da.frames == 2


def test_at_most_every_50_ms(tmp_path_factory):
    b = StatusBench(tmp_path_factory.getbasetemp() / "unicos_build", tMinPeriod=50)
    sent = []
    for k in range(100):                            # a change every 10 ms scan for 1 s
        b.set_table([k] * 96)
        b.step()
        if b.da.frames > len(sent):
            sent.append(b.scans)
    gaps = [y - x for x, y in zip(sent, sent[1:])]
    assert gaps and min(gaps) >= 5, gaps            # 50 ms = 5 scans
    assert len(sent) == 20                          # and no less often
    b.step(10)
    assert b.da.status[(1, 0)] == [99] * 96         # the newest table arrives


def test_pair_and_a_refusing_driver(tmp_path_factory):
    b = StatusBench(tmp_path_factory.getbasetemp() / "unicos_build", xRedundant=True,
                    tRetry=50, uMaxRetries=1)
    b.da.fail_next(4, code=4)
    b.set_table([5] * 96)
    b.step(12)
    assert b.db.status[(1, 0)] == [5] * 96
    assert b.da.status == {} and b.s["xError"] and b.s["eErrorId"] == UERR["MIP_UNI_ERR_EXCEPTION"]
    b.step(60)
    assert b.da.status[(1, 0)] == [5] * 96 and not b.s["xError"] and b.s["xCurrent"]


def test_parameters_sampled_at_enable_and_the_diagnostics(tmp_path_factory):
    """st_lib/CONVENTIONS.md: wOffset changed while enabled is taken at the next rising edge of
    xEnable; eState / eWaitReason say what the block waits for."""
    b = StatusBench(tmp_path_factory.getbasetemp() / "unicos_build", wOffset=100, tMinPeriod=50)
    t = [1] * 96
    b.set_table(t)
    b.step(10)
    assert b.da.status == {(1, 100): t} and b.s["xValid"] and b.s["xBusy"]
    assert b.s["eState"] == SSTATE["MIP_UNS_CURRENT"]
    assert b.s["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_CHANGE"]
    b.s["wOffset"] = 200                            # while enabled: not taken
    t = [2] * 96
    b.set_table(t)
    b.step(1)                                       # sent at once (the last one is 100 ms old)
    t2 = [3] * 96
    b.set_table(t2)
    b.step(1)                                       # within tMinPeriod: waits
    assert b.s["eState"] == SSTATE["MIP_UNS_PERIOD"]
    assert b.s["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_PERIOD"]
    b.step(10)
    assert b.da.status == {(1, 100): t2}
    b.s["xEnable"] = False
    b.step(1)
    assert b.s["eState"] == SSTATE["MIP_UNS_DISABLED"] and not b.s["xValid"]
    assert b.s["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_NONE"] and not b.s["xBusy"]
    b.s["xEnable"] = True                           # the rising edge takes wOffset
    b.step(10)
    assert b.da.status == {(1, 100): t2, (1, 200): t2} and b.s["xCurrent"]
