"""The shipped TwinCAT and CODESYS glue (dist/glue/) with the strict stand-ins against a Modbus
server into which every documented error is injected once (issue 47): an exception reply, the
server busy (exception 06), no answer, a refused connection. Each read and write ends in the
vendor's named error, shown for one call as xReadError (or latched as xWriteError) with the
code in nReadErrId / eReadError, within a bounded number of cycles, and the reads recover by
themselves when the server answers again: never a silent wait. In virtual time, except where a
real socket has to stay silent."""
import socket
import threading
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

from mipcosim import vendor_glue as glue
from plcharness import Plc
from standin_server import ScriptedServer

TYPES = REPO / "st_lib" / "core" / "MIP_Types.st"

CALL = {
    "twincat": "io(sIPAddr := '127.0.0.1', nUnitID := 16#FF, nReadAddr := 5, nWriteAddr := 200,\n"
               "   tTimeout := T#500MS, xEnable := TRUE, xWriteReq := xWr, aWrite := aW,\n"
               "   uWriteLen := 3);\n",
    "codesys": "io(aIPaddr := ip, uiUnitId := 255, uiReadAddr := 5, uiWriteAddr := 200,\n"
               "   xEnable := TRUE,\n"
               "   xWriteReq := xWr, aWrite := aW, uWriteLen := 3);\n",
}
FB = {"twincat": "MIP_TcModbusIo", "codesys": "MIP_CdsModbusIo"}
# the code a read shows for each injected error (TwinCAT nReadErrId, CODESYS eReadError;
# CODESYS also eReadException for the two exceptions)
EXPECTED = {
    "twincat": {"exception": 0x8004, "busy": 0x8006, "silent": 0x745, "refused": 0x80070000 + 111},
    "codesys": {"exception": 51, "busy": 51, "silent": 56, "refused": 101},
}
ERR_VAR = {"twincat": "NREADERRID", "codesys": "EREADERROR"}
WR_ERR_VAR = {"twincat": "NWRITEERRID", "codesys": "EWRITEERROR"}


def program(family):
    return f"""
PROGRAM MAIN
VAR
  io : {FB[family]};
  ip : ARRAY[0..3] OF BYTE := [127, 0, 0, 1];
  xWr : BOOL;
  aW : MIP_T_Block;
  nRdOk, nRdErr : UDINT;
END_VAR
{CALL[family]}IF io.xReadValid THEN nRdOk := nRdOk + 1; END_IF;
IF io.xReadError THEN nRdErr := nRdErr + 1; END_IF;
END_PROGRAM

CONFIGURATION C
RESOURCE R ON PLC
TASK t(INTERVAL := T#10ms, PRIORITY := 0);
PROGRAM inst WITH t : MAIN;
END_RESOURCE
END_CONFIGURATION
"""


@pytest.fixture
def build(tmp_path):
    def make(family, port):
        from mipcosim import programs as L
        src = tmp_path / f"main.{family}.st"
        src.write_text(program(family))
        cfg = tmp_path / "plc.conf"
        cfg.write_text(L.outstation_config(port, channel=True))
        files = [TYPES, *glue.STANDINS[family], *glue.GLUE[family], src]
        return Plc.build(files, workdir=tmp_path / "w", compiler="stc", config=cfg)
    return make


def _until(plc, cond, limit):
    for n in range(limit):
        if cond():
            return n
        plc.scan(1)
    raise AssertionError(f"not within {limit} cycles: a silent wait")


@pytest.mark.parametrize("family", ["twincat", "codesys"])
def test_exception_and_busy_end_in_the_named_error_and_reads_recover(build, family):
    srv = ScriptedServer()
    try:
        plc = build(family, srv.port)
        _until(plc, lambda: plc["INST.NRDOK"] > 2, 50)
        for fault, code in (("exception", 4), ("busy", 6)):
            srv.exception = code
            errs = plc["INST.NRDERR"]
            _until(plc, lambda: plc["INST.NRDERR"] > errs, 50)
            assert plc[f"INST.IO.{ERR_VAR[family]}"] == EXPECTED[family][fault]
            if family == "codesys":
                assert plc["INST.IO.EREADEXCEPTION"] == code
            # a write in the meantime: latched as xWriteError until xWriteReq falls
            plc["INST.XWR"] = True
            _until(plc, lambda: plc["INST.IO.XWRITEERROR"], 50)
            assert not plc["INST.IO.XWRITEDONE"]
            assert plc[f"INST.IO.{WR_ERR_VAR[family]}"] == EXPECTED[family][fault]
            plc["INST.XWR"] = False
            plc.scan(2)
            assert not plc["INST.IO.XWRITEERROR"]
            srv.exception = 0
            oks = plc["INST.NRDOK"]
            _until(plc, lambda: plc["INST.NRDOK"] > oks, 50)     # recovered by itself
        plc["INST.XWR"] = True
        _until(plc, lambda: plc["INST.IO.XWRITEDONE"], 50)
        assert srv.holding[200:203] == [0, 0, 0]
    finally:
        srv.close()


@pytest.mark.parametrize("family", ["twincat", "codesys"])
def test_no_answer_ends_in_the_named_error(build, family):
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(4)
    conns = []

    def accept():
        while True:
            try:
                conns.append(silent.accept())
            except OSError:
                return
    threading.Thread(target=accept, daemon=True).start()
    try:
        plc = build(family, silent.getsockname()[1])
        _until(plc, lambda: plc["INST.NRDERR"] > 0, 150)
        assert plc[f"INST.IO.{ERR_VAR[family]}"] == EXPECTED[family]["silent"]
        assert plc["INST.NRDOK"] == 0
    finally:
        silent.close()
        for c, _ in conns:
            c.close()


@pytest.mark.parametrize("family", ["twincat", "codesys"])
def test_a_refused_connection_ends_in_the_named_error(build, family):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    plc = build(family, port)
    _until(plc, lambda: plc["INST.NRDERR"] > 1, 150)
    assert plc[f"INST.IO.{ERR_VAR[family]}"] == EXPECTED[family]["refused"]


def test_codesys_glue_shows_a_failed_connect_and_tries_again(build):
    """ClientTCP that cannot connect (the address left at 255.255.255.255): after the glue's
    tConnectTimeOut (5 s) a read error with TcpConnectTimeout (103) in wReadStatus, and a new
    rising edge of xConnect; with the address set it connects at that edge and reads."""
    srv = ScriptedServer()
    try:
        plc = build("codesys", srv.port)
        for i in range(4):
            plc[f"INST.IP[{i}]"] = 255
        n = _until(plc, lambda: plc["INST.NRDERR"] > 0, 600)
        assert n > 450                                   # not before the 5 s
        assert plc["INST.IO.ECLIENTERROR"] == 103 and plc["INST.IO.WREADSTATUS"] == 103
        for i, b in enumerate((127, 0, 0, 1)):
            plc[f"INST.IP[{i}]"] = b
        _until(plc, lambda: plc["INST.NRDOK"] > 0, 600)
    finally:
        srv.close()
