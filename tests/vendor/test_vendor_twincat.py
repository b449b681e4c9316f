"""TwinCAT (issue 36): the shipped glue (dist/glue/twincat/MIP_TcModbusIo) with the stand-ins
of Tc2_ModbusSrv's FB_MBReadRegs / FB_MBWriteRegs (standins/twincat/) and the portable blocks,
in the example programs' place of the located I/O (mipcosim/glue.py), over the emulator in
co-simulation: the record-for-record check of the demo (mipcosim/check.py), and the handshake
mistake of the family (bBusy's fall taken as done without looking at bError)."""
import itertools

import pytest

from mipcosim import glue
from mipcosim import layout as L
from vendor_helpers import assert_exact, run, run_outstation, sources

FAMILY = "twincat"


def test_twincat_glue_transfers_a_logger_with_loss_and_a_restart(vendor_workdir):
    """Quick tier: one short run of the outstation with the glue (the central: the example
    program), 10 % loss and an outstation restart mid read-out."""
    ch, finished, reps, tot, requests = run(FAMILY, vendor_workdir / "quick", 0.1, "outstation",
                                            roles=("outstation",))
    assert_exact(ch, finished, reps, tot, "outstation")
    assert requests > 50         # the reads and writes went through the stand-ins' channel


MATRIX = list(itertools.product([0.0, 0.1, 0.3], ["none", "outstation", "central"]))


@pytest.mark.slow
@pytest.mark.parametrize("loss,restart", MATRIX,
                         ids=[f"loss{int(p * 100)}-{r}" for p, r in MATRIX])
def test_twincat_glue_matrix(vendor_workdir, loss, restart):
    ch, finished, reps, tot, _ = run(FAMILY, vendor_workdir / "matrix", loss, restart, seed=11)
    assert_exact(ch, finished, reps, tot, restart)


def _failing_writes(workdir, mistaken):
    """The outstation's writes all fail (the modem refuses the write address: exception 02,
    nErrId 16#8002); with `mistaken` glue that takes bBusy's fall as done without bError (the
    glue as shipped: the build of the transfer test)."""
    text = None
    if mistaken:
        good = glue.GLUE[FAMILY][0].read_text()
        text = good.replace("xWriteDone := NOT fbWr.bError;", "xWriteDone := TRUE;") \
                   .replace("xWriteError := fbWr.bError;", "xWriteError := FALSE;")
        assert text != good
    src = sources(FAMILY, workdir, text, roles=("outstation",))
    return run_outstation(FAMILY, workdir, src, 3, {12: 3, glue.WRITE_ADDR_WORD: 4000},
                          extra=("IO1.NWRITEERRID",))


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
