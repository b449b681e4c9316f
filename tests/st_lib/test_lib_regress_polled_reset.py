"""Regression: polled drive with radio loss must leave the reset phase (st_lib 445832d .. fix).

With the polled drive, every acknowledgement 0 the receiver wrote for a reset marker reached the
sender as a new request telegram while the own modem was still repeating that reset on the
radio (read-status bit 4 set). The sender answered it with a new marker, which replaced the
unconfirmed block, was answered again, and so on: the own modem never reported the reset
confirmed and MIP_Sender stayed in MIP_SND_RESET (a state removed since) for good (thousands
of retransmissions, nothing reported). Co-simulated with the example programs and the
emulator core, realistic radio timing, the cases that stalled before the fix; every record is
checked exactly once.

Since sessions open with record 1 (st_lib/PROTOCOL.md P6) there is no reset phase any more; the
schedules stay as polled, lossy liveness cases of the whole chain."""
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

if not (REPO / "build" / "cosim" / "libmipcosim.so").is_file():
    pytest.fail("build/cosim/libmipcosim.so not built: run make first (these tests cannot run without it)", pytrace=False)

from mipcosim.check import check, summary          # noqa: E402
from mipcosim.sim import SEC, LoggerLink, Radio, Setup  # noqa: E402

RECORDS = 20


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("regress_polled_reset")


@pytest.mark.parametrize("loss,seed", [(0.05, 4), (0.3, 2), (0.4, 1), (0.4, 5)])
def test_polled_lossy_transfer_leaves_reset_phase(workdir, loss, seed):
    st = Setup(loss=loss, seed=seed, records=RECORDS, payload=122, timeout_ms=1500,
               polled=True, radio=Radio.realistic())
    with LoggerLink(st, workdir) as ch:
        finished = ch.run_to_end(200 * SEC, step_ns=SEC // 10, settle_ns=3 * SEC)
        reps = check(ch)
        tot = summary(reps)
        snd = ch.plcs[("out", 1)]
        retrans = snd["OUTSTATION.APP.SND.UDIRETRANSMISSIONS"]
        state = snd["OUTSTATION.APP.SND.ESTATE"]
        t_end = ch.now / SEC
    problems = [p for r in reps for p in r.problems]
    assert finished, (f"not all records read out after {t_end:.0f} s "
                      f"(sender state {state}, {retrans} retransmissions): {tot} {problems}")
    assert not problems, problems
    # a handful per lost telegram, not one per request telegram
    assert retrans < 10 * RECORDS, retrans
