"""MIP_UnicosStatus against the independent WinCC OA stand-in: the table goes whole once, then on
a change, never twice within 50 ms; a pair gets it twice over; a driver that refuses is retried
with the newest table and named."""
from unicos_bench import UERR, StatusBench


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
