"""S7 (issue 36): the shipped glue (dist/glue/s7/MIP_S7ModbusIo.scl, TIA SCL, read by stc's SCL
dialect) with a stand-in of MB_CLIENT (standins/s7/) and the portable blocks, in the example
programs' place of the located I/O (mipcosim/glue.py), over the emulator in co-simulation: the
record-for-record check of the demo (mipcosim/check.py), and the handshake mistake of the
family (DONE taken as a level)."""
import itertools

import pytest

from mipcosim import glue
from mipcosim import layout as L
from vendor_helpers import assert_exact, run, run_outstation, sources

FAMILY = "s7"


def test_s7_glue_transfers_a_logger_with_loss_and_a_restart(vendor_workdir):
    """Quick tier: one short run of the outstation with the glue (the central: the example
    program), 30 % loss and an outstation restart mid read-out; read and write take turns on
    one MB_CLIENT instance."""
    ch, finished, reps, tot, requests = run(FAMILY, vendor_workdir / "s7-quick", 0.3, "outstation",
                                            roles=("outstation",))
    assert_exact(ch, finished, reps, tot, "outstation")
    assert requests > 50


MATRIX = list(itertools.product([0.0, 0.1, 0.3], ["none", "outstation", "central"]))


@pytest.mark.slow
@pytest.mark.parametrize("loss,restart", MATRIX,
                         ids=[f"loss{int(p * 100)}-{r}" for p, r in MATRIX])
def test_s7_glue_matrix(vendor_workdir, loss, restart):
    ch, finished, reps, tot, _ = run(FAMILY, vendor_workdir / "s7-matrix", loss, restart, seed=17)
    assert_exact(ch, finished, reps, tot, restart)


def test_s7_done_taken_as_a_level_ends_in_a_named_error(vendor_workdir):
    """The integrator's mistake: MB_CLIENT's DONE / ERROR (TRUE for the one call in which a
    request ends) looked at after a second call of the instance in the same cycle, as if they
    were levels. The glue then never sees a request end. The blocks bound that wait: the write
    handshake ends a request the caller has not ended within 10 s (MIP_WriteChannel's
    tTimeout) as a failed write (udiWriteErrors), the sender retransmits, and after uMaxRetries
    the transfer ends with MIP_ERR_NO_ACK, a named error; none is reported done. (Before the
    bound, the sender waited in MIP_WAIT_WRITE for as long as the run lasted.)"""
    good = glue.GLUE[FAMILY][0].read_text()
    old = "      #pause := FALSE;\n      IF #mb.DONE OR #mb.ERROR THEN"
    assert old in good
    bad = good.replace(old, "      #pause := FALSE;\n"
                       "      #mb(REQ := FALSE, DISCONNECT := FALSE, MB_MODE := 0, MB_DATA_ADDR := #readAddr,\n"
                       "          MB_DATA_LEN := 125, MB_DATA_PTR := #buf, CONNECT := #connect);\n"
                       "      IF #mb.DONE OR #mb.ERROR THEN")
    src = sources(FAMILY, vendor_workdir / "s7-level", bad, roles=("outstation",))
    r = run_outstation(FAMILY, vendor_workdir / "s7-level", src, 45, {12: 3},
                       extra=("SND.UDIWRITEERRORS", "IO1.WRITEDONE"))
    errors = L.enum_values("E_MIP_Error")
    assert r["SRC.UTRANSFERSDONE"] == 0
    assert r["SRC.UTRANSFERSFAILED"] >= 1
    assert r["SRC.WLASTERROR"] == errors["MIP_ERR_NO_ACK"]
    assert r["SND.UDIWRITEERRORS"] >= 1 and not r["IO1.WRITEDONE"]
