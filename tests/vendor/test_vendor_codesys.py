"""CODESYS (issue 36): the shipped glue (dist/glue/codesys/MIP_CdsModbusIo) with the stand-ins
of ModbusFB's ClientTCP / ClientRequestReadHoldingRegisters / ClientRequestWriteMultipleRegisters
(standins/codesys/) and the portable blocks, in the example programs' place of the located I/O
(mipcosim/vendor_glue.py), over the emulator in co-simulation: the record-for-record check of the demo
(mipcosim/check.py), and the handshake mistake of the family (xExecute held TRUE)."""
import itertools

import pytest

from mipcosim import vendor_glue as glue
from mipcosim import programs as L
from vendor_helpers import assert_exact, run, run_outstation, sources
import realistic

FAMILY = "codesys"


def test_codesys_glue_transfers_a_logger_with_loss_and_a_restart(vendor_workdir):
    """Quick tier: one short run of the outstation with the glue (the central: the example
    program), 10 % loss and a central restart mid read-out; the read and the write requests
    share one ClientTCP (the stand-in takes them one after the other)."""
    ch, finished, reps, tot, requests = run(FAMILY, vendor_workdir / "cds-quick", 0.1, "central",
                                            roles=("outstation",))
    assert_exact(ch, finished, reps, tot, "central")
    assert requests > 50


MATRIX = list(itertools.product([0.0, 0.1, 0.3], ["none", "outstation", "central"]))


@pytest.mark.slow
@pytest.mark.parametrize("loss,restart", MATRIX,
                         ids=[f"loss{int(p * 100)}-{r}" for p, r in MATRIX])
def test_codesys_glue_matrix(vendor_workdir, loss, restart):
    ch, finished, reps, tot, _ = run(FAMILY, vendor_workdir / "cds-matrix", loss, restart, seed=13)
    assert_exact(ch, finished, reps, tot, restart)


def test_codesys_xexecute_held_ends_in_a_named_error(vendor_workdir):
    """The integrator's mistake: the read request's xExecute held TRUE. ModbusFB's behaviour
    model then does one request and shows its xDone until xExecute falls: the glue takes the
    same registers as a new read in every call, the sender never sees its acknowledgement and
    ends each transfer after uMaxRetries (3) retransmissions with MIP_ERR_NO_ACK, a named
    error in bounded time; nothing is reported done. The glue as shipped drops xExecute after
    every request (the transfer test above)."""
    good = glue.GLUE[FAMILY][0].read_text()
    held = good.replace("  xRdExec := FALSE;               // the next call resets the request block",
                        "  xRdExec := TRUE;")
    assert held != good
    src = sources(FAMILY, vendor_workdir / "cds-held", held, roles=("outstation",))
    r = run_outstation(FAMILY, vendor_workdir / "cds-held", src, 3, {12: 3},
                       extra=("IO1.FBRD.XDONE",))
    errors = L.enum_values("E_MIP_Error")
    assert r["APP.SRC.UTRANSFERSDONE"] == 0
    assert r["APP.SRC.UTRANSFERSFAILED"] >= 1
    assert r["APP.SRC.WLASTERROR"] == errors["MIP_ERR_NO_ACK"]
    assert r["IO1.FBRD.XDONE"]                     # the one request's xDone, still shown


def _without_reply_timeout():
    """The glue with its two request calls leaving udiReplyTimeout and uiMaxRetries at the
    library's defaults (50 ms, 0): the field issue 47 names."""
    good = glue.GLUE[FAMILY][0].read_text()
    bad = good.replace("udiReplyTimeout := udiReplyTimeout, uiMaxRetries := uiMaxRetries,", "")
    assert good.count("udiReplyTimeout := udiReplyTimeout") == 2 and "udiReplyTimeout :=" not in bad
    return bad


def test_codesys_glue_without_reply_timeout_fails_with_reply_timeout(vendor_workdir):
    """Over the realistic radio with a 9,600 bit/s line to the modem, a 125-register read takes
    about 0.3 s: with udiReplyTimeout at the library's 50 ms every read and write ends in
    ModbusFB's ReplyTimeout (56), which the sender shows as its link error; nothing is read
    out. The shipped glue (2 s) passes the same run (test below)."""
    wd = vendor_workdir / "cds-noreply"
    src = sources(FAMILY, wd, _without_reply_timeout(), roles=("outstation",))
    r = realistic.run_for(src, ("outstation",), wd, 20,
                          ("OUTSTATION.IO1.EREADERROR", "OUTSTATION.IO1.EWRITEERROR",
                           "OUTSTATION.APP.SND.XLINKERROR", "OUTSTATION.APP.SND.WLINKERROR",
                           "OUTSTATION.APP.SRC.UTRANSFERSDONE"))
    assert r["OUTSTATION.IO1.EREADERROR"] == 56
    assert r["OUTSTATION.APP.SND.XLINKERROR"] and r["OUTSTATION.APP.SND.WLINKERROR"] == 56
    assert r["OUTSTATION.APP.SRC.UTRANSFERSDONE"] == 0


def test_codesys_glue_passes_the_realistic_radio_at_30_percent_loss(vendor_workdir):
    wd = vendor_workdir / "cds-realistic"
    src = sources(FAMILY, wd, roles=("outstation",))
    finished, secs, tot, problems = realistic.run_to_end(src, ("outstation",), wd)
    assert finished, f"not read out after {secs:.0f} s: {tot} {problems}"
    assert problems == [] and tot["lost"] == 0 and tot["duplicated"] == 0
    assert tot["records"] == realistic.RECORDS
