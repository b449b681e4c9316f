"""TwinCAT (issue 36): the shipped glue (dist/glue/twincat/MIP_TcModbusIo) with the stand-ins
of Tc2_ModbusSrv's FB_MBReadRegs / FB_MBWriteRegs (standins/twincat/) and the portable blocks,
in the example programs' place of the located I/O (mipcosim/vendor_glue.py), over the emulator in
co-simulation: the record-for-record check of the demo (mipcosim/check.py), and the handshake
mistake of the family (bBusy's fall taken as done without looking at bError)."""
import itertools
from pathlib import Path

import pytest

from mipcosim import vendor_glue as glue
from mipcosim import programs as L
from vendor_helpers import assert_exact, run, run_outstation, sources
import realistic

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
    assert r["APP.SRC.UTRANSFERSDONE"] == 0
    assert r["APP.SRC.UTRANSFERSFAILED"] >= 1
    assert r["APP.SRC.WLASTERROR"] == errors["MIP_ERR_NO_ACK"]


def _central_sources(workdir, unit_id=True):
    """The central with the glue; unit_id False: its call leaves nUnitID out (the FB's default
    16#FF, the manual's value for a device addressed directly, not for a station behind the
    MDP-810: the field issue 47 names)."""
    src = sources(FAMILY, workdir, roles=("central",))
    if not unit_id:
        prog = Path(src["central"][-1])
        text = prog.read_text()
        bad = text.replace("nUnitID := 1, ", "")
        assert bad != text
        copy = prog.with_name("nounit_" + prog.name)
        copy.write_text(bad)
        src["central"][-1] = str(copy)
    return src


def test_twincat_glue_without_unit_id_fails_with_the_gateway_exception(vendor_workdir):
    """At the MDP-810 the unit id selects the station. Left out, FB_MBReadRegs sends its default
    16#FF; the MDP answers exception 0B (gateway target failed to respond), TwinCAT's 16#800B:
    the receiver's link error, nothing read out. The shipped call passes (test below)."""
    wd = vendor_workdir / "tc-nounit"
    r = realistic.run_for(_central_sources(wd, unit_id=False), ("central",), wd, 20,
                          ("CENTRAL.IO1.NREADERRID", "CENTRAL.APP.STA1.RCV.XLINKERROR",
                           "CENTRAL.APP.STA1.RCV.WLINKERROR", "CENTRAL.APP.STA1.RCV.UDIRECORDS"))
    assert r["CENTRAL.IO1.NREADERRID"] == 0x800B
    assert r["CENTRAL.APP.STA1.RCV.XLINKERROR"] and r["CENTRAL.APP.STA1.RCV.WLINKERROR"] == 0x800B
    assert r["CENTRAL.APP.STA1.RCV.UDIRECORDS"] == 0


@pytest.mark.slow
def test_twincat_glue_passes_the_realistic_radio_at_30_percent_loss(vendor_workdir):
    """Full tier: a second build of the four-station central (about 20 s); the CODESYS glue's
    realistic run stays quick."""
    wd = vendor_workdir / "tc-realistic"
    finished, secs, tot, problems = realistic.run_to_end(_central_sources(wd), ("central",), wd)
    assert finished, f"not read out after {secs:.0f} s: {tot} {problems}"
    assert problems == [] and tot["lost"] == 0 and tot["duplicated"] == 0
    assert tot["records"] == realistic.RECORDS
