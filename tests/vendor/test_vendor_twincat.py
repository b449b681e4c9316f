"""TwinCAT (issue 36): the shipped glue (dist/glue/twincat/MIP_TcModbusIo) with the stand-ins
of Tc2_ModbusSrv's FB_MBReadRegs / FB_MBWriteRegs (standins/twincat/) and the portable blocks,
in the example programs' place of the located I/O (mipcosim/glue.py), over the emulator in
co-simulation: the record-for-record check of the demo (mipcosim/check.py), and the handshake
mistake of the family (bBusy's fall taken as done without looking at bError)."""
import itertools
from pathlib import Path

import pytest

from mipcosim import glue
from mipcosim import layout as L
from mipcosim.check import check, summary
from mipcosim.sim import SEC, Chain, Setup

FAMILY = "twincat"


def run(workdir, loss, restart, records=24, per_transfer=7, seed=7):
    src = {r: glue.sources(FAMILY, r, Path(workdir) / "src") for r in ("outstation", "central")}
    st = Setup(loss=loss, seed=seed, records=records, per_transfer=per_transfer, log_period_ms=50,
               sources=src, channel=True)
    with Chain(st, workdir) as ch:
        if restart != "none":
            ch.run_for(SEC)          # mid read-out
            ch.restart(("out", 1) if restart == "outstation" else ("cen", 0))
        finished = ch.run_to_end(600 * SEC)
        reps = check(ch)
        requests = ch.plcs[("out", 1)].device_stats()["trm"]["requests"]
        return ch, finished, reps, summary(reps), requests


def assert_exact(ch, finished, reps, tot, restart, records=24):
    problems = [p for r in reps for p in r.problems]
    assert finished, f"not all records read out after {ch.now / SEC:.0f} s: {tot} {problems}"
    assert problems == []
    assert tot["lost"] == 0
    for r in reps:
        assert r.records >= records, (r.name, r.records)
    if restart == "none":
        assert tot["duplicated"] == 0 and tot["failed_reported"] == 0
        assert tot["records"] == records


def test_twincat_glue_transfers_a_logger_with_loss_and_a_restart(vendor_workdir):
    """Quick tier: one short run, 10 % loss and an outstation restart mid read-out."""
    ch, finished, reps, tot, requests = run(vendor_workdir / "quick", 0.1, "outstation")
    assert_exact(ch, finished, reps, tot, "outstation")
    assert requests > 50         # the reads and writes went through the stand-ins' channel


MATRIX = list(itertools.product([0.0, 0.1, 0.3], ["none", "outstation", "central"]))


@pytest.mark.slow
@pytest.mark.parametrize("loss,restart", MATRIX,
                         ids=[f"loss{int(p * 100)}-{r}" for p, r in MATRIX])
def test_twincat_glue_matrix(vendor_workdir, loss, restart):
    ch, finished, reps, tot, _ = run(vendor_workdir / "matrix", loss, restart, seed=11)
    assert_exact(ch, finished, reps, tot, restart)


def _failing_writes(workdir, mistaken):
    """The outstation's writes all fail (the modem refuses the write address: exception 02,
    nErrId 16#8002); with `mistaken` glue that takes bBusy's fall as done without bError (the
    glue as shipped: the build of the transfer test)."""
    workdir = Path(workdir)
    src = {r: glue.sources(FAMILY, r, workdir / "src") for r in ("outstation", "central")}
    if mistaken:
        good = Path(src["outstation"][-2]).read_text()
        bad = good.replace("xWriteDone := NOT fbWr.bError;", "xWriteDone := TRUE;") \
                  .replace("xWriteError := fbWr.bError;", "xWriteError := FALSE;")
        assert bad != good
        path = workdir / "src" / "MIP_TcModbusIo_mistaken.twincat.st"
        path.write_text(bad)
        src["outstation"][-2] = str(path)
    st = Setup(seed=7, records=24, per_transfer=7, log_period_ms=50, timeout_ms=300,
               sources=src, channel=True)
    with Chain(st, workdir) as ch:
        ch.plcs[("out", 1)]["%MW12"] = 3          # the sender's uMaxRetries
        ch.plcs[("out", 1)][f"%MW{glue.WRITE_ADDR_WORD}"] = 4000   # no such write register
        ch.run_for(3 * SEC)
        o = ch.plcs[("out", 1)]
        return {n: o[f"OUTSTATION.{n}"] for n in
                ("SRC.UTRANSFERSFAILED", "SRC.UTRANSFERSDONE", "SRC.WLASTERROR", "IO1.NWRITEERRID")}


@pytest.mark.parametrize("mistaken", [False, True], ids=["checked", "bbusy-fall-as-done"])
def test_twincat_failed_writes_end_in_a_named_error(vendor_workdir, mistaken):
    """A write that fails is never a silent wait: with the glue as shipped (bError checked) the
    sender sees xWriteError; with the integrator's mistake (bBusy's fall taken as done) it
    waits for an acknowledgement that cannot come. Either way each transfer ends after
    uMaxRetries retransmissions with MIP_ERR_NO_ACK, a named error, within a bounded time
    (3 retransmissions of tTimeout 300 ms), and none is reported done."""
    r = _failing_writes(vendor_workdir / ("mistaken" if mistaken else "checked"), mistaken)
    errors = L.enum_values("E_MIP_Error")
    assert r["IO1.NWRITEERRID"] == 0x8002          # the stand-in's exception 02: "invalid address"
    assert r["SRC.UTRANSFERSDONE"] == 0
    assert r["SRC.UTRANSFERSFAILED"] >= 1
    assert r["SRC.WLASTERROR"] == errors["MIP_ERR_NO_ACK"]
