"""Warm restarts with rollback in the co-simulation (issue 16, st_lib/PROTOCOL.md W0-W3): the
example programs keep their blocks, logger and store in RETAIN; a restart brings a PLC back
with its last snapshot (kill -9) or one taken at the stop (graceful). With the blocks' snapshot
gate (flag bit 3, xRetained) nothing is lost, duplicated or failed; without it the same
restarts lose and duplicate transfers (W0), which is what the gate is for. The bidirectional
programs (MIP_Link, W4) likewise, both streams. `make soak SOAK_ARGS=--warm-restarts` (with
`--bidi` for MIP_Link) is the long run."""
import pytest

from mipcosim.check import check, summary
from mipcosim.sim import LoggerLink, Setup, SEC


def run(workdir, retain, seed, polled=False, bidi=False, window=1):
    st = Setup(stations=1, loss=0.3, seed=seed, records=600, per_transfer=50, timeout_ms=300,
               retain=retain, polled=polled, bidi=bidi, window=window)
    with LoggerLink(st, workdir) as ch:
        k = 0
        while ch.now < 900 * SEC and not ch.finished():
            ch.run_for(SEC)
            if ch.now >= (k + 1) * 7 * SEC:
                ch.restart(("out", 1) if k % 2 == 0 else ("cen", 0), warm=True,
                           graceful=k % 3 == 2)
                k += 1
        finished = ch.finished()
        ch.run_for(3 * SEC)
        ch.windows = ch.sender_windows()
        reps = check(ch)
        return finished, k, ch.retain_stats(), summary(reps), [p for r in reps for p in r.problems], \
            ch.windows


@pytest.mark.parametrize("seed,polled", [(1, False), (2, False), (3, True)])
def test_warm_restarts_with_the_gate_lose_and_duplicate_nothing(tmp_path, seed, polled):
    finished, k, rs, tot, problems, _ = run(tmp_path, True, seed, polled)
    assert finished and k >= 5
    assert rs["restored"] == k                       # every restart was warm, from a snapshot
    assert problems == []
    assert tot["records"] == 600 and tot["lost"] == 0 and tot["duplicated"] == 0
    assert tot["failed_reported"] == 0 and tot["receiver_reports"] == 0 and tot["cut_by_restart"] == 0


def test_retained_pipelined_sender_warm_restarts_lose_and_duplicate_nothing(tmp_path):
    """MIP_Sender with uWindow 2 and xRetained (P27 with W1: the pipelined record waits for its
    own snapshot): the same warm restarts, the sender pipelines, nothing lost or doubled."""
    finished, k, rs, tot, problems, windows = run(tmp_path, True, 7, window=2)
    assert finished and k >= 4      # it ends sooner than window 1: fewer restarts on the way
    assert rs["restored"] == k
    assert windows == {2}
    assert problems == []
    assert tot["records"] == 600 and tot["lost"] == 0 and tot["duplicated"] == 0
    assert tot["failed_reported"] == 0 and tot["receiver_reports"] == 0 and tot["cut_by_restart"] == 0


def test_warm_restarts_without_the_gate_lose_or_duplicate(tmp_path):
    """PROTOCOL.md W0: periodic snapshots alone (the blocks do not wait for one) roll a side
    back behind what its peer saw."""
    finished, k, rs, tot, problems, _ = run(tmp_path, False, 1)
    assert rs["restored"] == k
    assert tot["lost"] + tot["duplicated"] > 0 and problems


@pytest.mark.parametrize("seed,polled,window", [(4, False, 1), (5, True, 1), (6, False, 2)])
def test_bidirectional_warm_restarts_with_the_gate_lose_and_duplicate_nothing(tmp_path, seed,
                                                                               polled, window):
    """MIP_Link (W4): both streams, warm restarts of either side, kill -9 and graceful. uWindow 2
    is configured in the third case: MIP_Link runs window 1 (P27)."""
    finished, k, rs, tot, problems, windows = run(tmp_path, True, seed, polled, bidi=True,
                                                  window=window)
    assert finished and k >= 5
    assert rs["restored"] == k
    assert problems == []
    assert tot["records"] == 1200 and tot["lost"] == 0 and tot["duplicated"] == 0
    assert tot["failed_reported"] == 0 and tot["receiver_reports"] == 0 and tot["cut_by_restart"] == 0
    assert windows == {1}


def test_bidirectional_warm_restarts_without_the_gate_fail_transfers(tmp_path):
    """Without xRetained the same restarts roll a side back behind what its peer saw: here
    transfers fail on both streams (MIP_ERR_PEER_OUT_OF_STEP at the sender, SENDER_RESET at the
    receiver), which a warm restart must not cause."""
    finished, k, rs, tot, problems, _ = run(tmp_path, False, 4, bidi=True)
    assert rs["restored"] == k
    assert tot["failed_reported"] + tot["lost"] + tot["duplicated"] > 0 and problems
