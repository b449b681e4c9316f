"""The TwinCAT stand-ins (standins/twincat/) against a Modbus TCP server, in virtual time:
what the manual says of FB_MBReadRegs / FB_MBWriteRegs / FB_MBReadWriteRegs (a rising edge
starts a request, bBusy until it has ended, bError and nErrId, cbRead, the data at pDestAddr /
from pSrcAddr), and the requests go on the wire as the program asked (the server's log).
Every nErrId of the table in docs/wiring-twincat.md#the-stand-ins is reached here; ERRIDS below
says which test reaches which."""
import socket
import threading
from pathlib import Path

import pytest

from plcharness import Plc
from rt_helpers import ModbusServer
from standin_server import ScriptedServer

REPO = Path(__file__).resolve().parents[2]

# nErrId -> the test that reaches it (docs/wiring-twincat.md#the-stand-ins has the same codes)
ERRIDS = {
    0x8001: "test_exception_replies_are_8000_plus_the_code",
    0x8002: "test_a_read_starts_on_the_edge_and_ends_when_bbusy_falls (exception 02), "
            "test_buffer_too_small_is_8002_without_a_request",
    0x8003: "test_a_read_starts_on_the_edge_and_ends_when_bbusy_falls (nQuantity 0), "
            "test_the_modbus_limits_are_8003_without_a_request",
    0x8004: "test_exception_replies_are_8000_plus_the_code, "
            "test_a_reply_that_does_not_fit_is_8004 (our choice)",
    0x8006: "test_exception_replies_are_8000_plus_the_code (busy, our choice)",
    0x745: "test_no_answer_is_ads_timeout, test_ttimeout_left_at_zero_fails_at_once",
    0x80070000 + 111: "test_a_refused_connection_is_a_win32_error",
}

STANDINS = [REPO / "standins" / "StandIn_Channel.twincat.st",
            REPO / "standins" / "twincat" / "Tc2_ModbusSrv.twincat.st"]

PROG = """
PROGRAM MAIN
VAR
  fbRd : FB_MBReadRegs;
  fbRd2 : FB_MBReadRegs;
  fbWr : FB_MBWriteRegs;
  fbRw : FB_MBReadWriteRegs;
  aRd : ARRAY[0..9] OF WORD;
  aRw : ARRAY[0..9] OF WORD;
  bRw : BOOL;
  nRwRdQty : WORD := 2;
  nRwWrQty : WORD := 3;
  cbRd : UDINT := 20;
  tTo : TIME := T#1S;
  aRd2 : ARRAY[0..9] OF WORD;
  aWr : ARRAY[0..9] OF WORD := [11, 22, 33];
  bRd, bRd2, bWr : BOOL;
  nAddr : WORD := 5;
  nQty : WORD := 3;
  nScans, nBusyScans : UDINT;
END_VAR
nScans := nScans + 1;
fbRd(sIPAddr := '127.0.0.1', nUnitID := 7, nQuantity := nQty, nMBAddr := nAddr,
     cbLength := cbRd, pDestAddr := ADR(aRd), bExecute := bRd, tTimeout := tTo);
fbRd2(sIPAddr := '127.0.0.1', nQuantity := 2, nMBAddr := 8,
      cbLength := SIZEOF(aRd2), pDestAddr := ADR(aRd2), bExecute := bRd2, tTimeout := T#1S);
fbWr(sIPAddr := '127.0.0.1', nQuantity := 3, nMBAddr := 20,
     cbLength := SIZEOF(aWr), pSrcAddr := ADR(aWr), bExecute := bWr, tTimeout := T#1S);
fbRw(sIPAddr := '127.0.0.1', nReadQuantity := nRwRdQty, nMBReadAddr := 30,
     nWriteQuantity := nRwWrQty, nMBWriteAddr := 40, cbDestLength := SIZEOF(aRw),
     pDestAddr := ADR(aRw), cbSrcLength := SIZEOF(aWr), pSrcAddr := ADR(aWr),
     bExecute := bRw, tTimeout := T#1S);
IF fbRd.bBusy THEN nBusyScans := nBusyScans + 1; END_IF
END_PROGRAM

CONFIGURATION C
RESOURCE R ON PLC
TASK t(INTERVAL := T#10ms, PRIORITY := 0);
PROGRAM inst WITH t : MAIN;
END_RESOURCE
END_CONFIGURATION
"""


def config(port, timeout="1s", fc23=False):
    from mipcosim import programs as L
    return L.outstation_config(port, channel=True, fc23=fc23).replace("timeout = 1s",
                                                                      f"timeout = {timeout}")


@pytest.fixture
def build(tmp_path):
    def make(port, timeout="1s", fc23=False):
        src = tmp_path / "main.twincat.st"
        src.write_text(PROG)
        cfg = tmp_path / "plc.conf"
        cfg.write_text(config(port, timeout, fc23))
        return Plc.build([*STANDINS, src], workdir=tmp_path / "w", compiler="stc", config=cfg)
    return make


def test_a_read_starts_on_the_edge_and_ends_when_bbusy_falls(build):
    srv = ModbusServer(size=3000)
    try:
        srv.holding[5:8] = [7, 8, 9]
        plc = build(srv.port)
        plc.scan(5)
        assert srv.log == []                        # no edge, no request
        plc["INST.BRD"] = True
        plc.scan(1)
        assert plc["INST.FBRD.BBUSY"]               # busy in the call with the edge
        plc.scan(5)
        assert not plc["INST.FBRD.BBUSY"] and not plc["INST.FBRD.BERROR"]
        assert [plc[f"INST.ARD[{i}]"] for i in range(4)] == [7, 8, 9, 0]
        assert plc["INST.FBRD.CBREAD"] == 6
        assert srv.log == [(3, 5, 3)]
        plc.scan(10)                                # bExecute held: no second request
        assert srv.log == [(3, 5, 3)]
        # a refused address: exception 02 = nErrId 16#8002, when bBusy falls
        plc["INST.BRD"] = False
        plc["INST.NADDR"] = 2999
        plc.scan(1)
        plc["INST.BRD"] = True
        plc.scan(6)
        assert not plc["INST.FBRD.BBUSY"] and plc["INST.FBRD.BERROR"]
        assert plc["INST.FBRD.NERRID"] == 0x8002
        # nQuantity 0: refused without a request
        plc["INST.BRD"] = False
        plc["INST.NQTY"] = 0
        plc.scan(1)
        plc["INST.BRD"] = True
        plc.scan(2)
        assert plc["INST.FBRD.BERROR"] and plc["INST.FBRD.NERRID"] == 0x8003
        assert len(srv.log) == 2
    finally:
        srv.close()


def test_two_blocks_share_the_connection_one_request_at_a_time(build):
    srv = ModbusServer(size=3000)
    try:
        srv.holding[8:10] = [81, 91]
        plc = build(srv.port)
        plc.scan(2)
        plc["INST.BRD"] = True
        plc["INST.BRD2"] = True
        plc["INST.BWR"] = True                      # three requests raised in one scan
        plc.scan(15)
        for fb in ("FBRD", "FBRD2", "FBWR"):
            assert not plc[f"INST.{fb}.BBUSY"] and not plc[f"INST.{fb}.BERROR"], fb
        assert sorted(srv.log) == [(3, 5, 3), (3, 8, 2), (16, 20, 3)]
        assert [plc["INST.ARD2[0]"], plc["INST.ARD2[1]"]] == [81, 91]
        assert srv.holding[20:23] == [11, 22, 33]
    finally:
        srv.close()


def test_no_answer_is_ads_timeout(build):
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(4)
    conns = []
    t = threading.Thread(target=lambda: conns.append(silent.accept()), daemon=True)
    t.start()
    try:
        plc = build(silent.getsockname()[1], timeout="200ms")
        plc["INST.BRD"] = True
        plc.scan(40)
        assert not plc["INST.FBRD.BBUSY"] and plc["INST.FBRD.BERROR"]
        assert plc["INST.FBRD.NERRID"] == 0x745
    finally:
        silent.close()
        for c, _ in conns:
            c.close()


def _edge(plc, var, scans=6):
    plc[f"INST.{var}"] = False
    plc.scan(1)
    plc[f"INST.{var}"] = True
    plc.scan(scans)


def test_exception_replies_are_8000_plus_the_code(build):
    """01..04: the documented return codes 16#8001..16#8004; 06 (server busy): 16#8006 by the
    same rule (our choice: the manual lists 16#8000..16#80FF as "internal TwinCAT Modbus TCP")."""
    srv = ScriptedServer()
    try:
        plc = build(srv.port)
        for code in (1, 2, 3, 4, 6):
            srv.exception = code
            _edge(plc, "BRD")
            assert not plc["INST.FBRD.BBUSY"] and plc["INST.FBRD.BERROR"], code
            assert plc["INST.FBRD.NERRID"] == 0x8000 + code
    finally:
        srv.close()


def test_buffer_too_small_is_8002_without_a_request(build):
    """cbLength < 2 * nQuantity: the manual says the buffer must hold nQuantity * 2 bytes; the
    code 16#8002 ("invalid address or length") is our choice of the two it could be."""
    srv = ModbusServer(size=3000)
    try:
        plc = build(srv.port)
        plc["INST.CBRD"] = 5                      # 3 registers need 6 bytes
        _edge(plc, "BRD", 2)
        assert plc["INST.FBRD.BERROR"] and plc["INST.FBRD.NERRID"] == 0x8002
        assert not plc["INST.FBRD.BBUSY"]
        assert srv.log == []
        plc["INST.CBRD"] = 6                      # exactly enough
        _edge(plc, "BRD")
        assert not plc["INST.FBRD.BERROR"] and srv.log == [(3, 5, 3)]
    finally:
        srv.close()


def test_the_modbus_limits_are_8003_without_a_request(build):
    """FC3 at most 125 registers, FC23's write at most 121 (the Modbus limits; the Beckhoff
    page says 1..128: our choice to refuse what no server takes, as 16#8003)."""
    srv = ScriptedServer()
    try:
        plc = build(srv.port)
        plc["INST.NQTY"] = 126
        _edge(plc, "BRD", 2)
        assert plc["INST.FBRD.BERROR"] and plc["INST.FBRD.NERRID"] == 0x8003
        plc["INST.NRWWRQTY"] = 122
        _edge(plc, "BRW", 2)
        assert plc["INST.FBRW.BERROR"] and plc["INST.FBRW.NERRID"] == 0x8003
        plc["INST.NRWWRQTY"] = 0
        _edge(plc, "BRW", 2)
        assert plc["INST.FBRW.NERRID"] == 0x8003
        assert srv.log == []
    finally:
        srv.close()


def test_read_write_regs_writes_then_reads(build):
    """FB_MBReadWriteRegs with the [device]'s fc23 = yes: one function 23 on the wire."""
    srv = ScriptedServer()
    try:
        srv.holding[30:32] = [301, 302]
        plc = build(srv.port, fc23=True)
        _edge(plc, "BRW")
        assert not plc["INST.FBRW.BBUSY"] and not plc["INST.FBRW.BERROR"]
        assert srv.log == [(23, 30, 2, 40, 3)]
        assert srv.holding[40:43] == [11, 22, 33]
        assert [plc["INST.ARW[0]"], plc["INST.ARW[1]"]] == [301, 302]
        assert plc["INST.FBRW.CBREAD"] == 4
    finally:
        srv.close()


def test_ttimeout_left_at_zero_fails_at_once(build):
    """tTimeout has no default in the manual (TIME: T#0s): the stand-in's stricter reading (our
    choice) is that T#0s has elapsed at once: 16#745 in the call of the edge, no request."""
    srv = ModbusServer(size=3000)
    try:
        plc = build(srv.port)
        plc["INST.TTO"] = 0
        _edge(plc, "BRD", 1)
        assert plc["INST.FBRD.BERROR"] and plc["INST.FBRD.NERRID"] == 0x745
        assert not plc["INST.FBRD.BBUSY"]
    finally:
        srv.close()


def test_a_refused_connection_is_a_win32_error(build):
    """Nothing listens: the runtime's status 1111 (ECONNREFUSED) becomes 16#80070000 + 111
    (our choice: TwinCAT gives a Win32 code in that range, which the stand-in cannot know)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()                                   # a port nobody listens on
    plc = build(port)
    _edge(plc, "BRD", 10)
    assert plc["INST.FBRD.BERROR"] and not plc["INST.FBRD.BBUSY"]
    assert plc["INST.FBRD.NERRID"] == 0x80070000 + 111


def test_a_reply_that_does_not_fit_is_8004(build):
    """A read of 3 registers answered with 1: the runtime refuses the reply (status 1071); the
    stand-in gives 16#8004 "Modbus server error" (our choice: the manual has no code for it)."""
    srv = ScriptedServer()
    try:
        plc = build(srv.port)
        srv.malformed = True
        _edge(plc, "BRD", 10)
        assert plc["INST.FBRD.BERROR"] and plc["INST.FBRD.NERRID"] == 0x8004
    finally:
        srv.close()
