"""The CODESYS stand-ins (standins/codesys/ModbusFB) against a Modbus TCP server, in virtual
time: what the ModbusFB help says of ClientTCP (settings read at xConnect's rising edge) and of
the request blocks (ETrigTo handshake, udiReplyTimeout 50 ms and uiMaxRetries 0 by default,
udiTimeOut, first come first served, eErrorID / eException). Every eErrorID of the table in
docs/wiring-codesys.md#the-stand-ins that the stand-in produces is reached here; ERRORS says
which test reaches which."""
import socket
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

from plcharness import Plc
from rt_helpers import ModbusServer
from standin_server import ScriptedServer

STANDINS = [REPO / "standins" / "StandIn_Channel.twincat.st",
            REPO / "standins" / "codesys" / "ModbusFB.codesys.st"]

# eErrorID (ModbusFB.Error) -> the test that reaches it
ERRORS = {
    50: "test_a_request_while_not_connected_ends_request_not_processed",
    51: "test_exception_replies_are_request_exception_with_the_code",
    52: "test_the_modbus_limits_are_a_parameter_error_without_a_request",
    57: "test_a_reply_that_does_not_fit_is_an_invalid_reply",
    56: "test_a_late_reply_is_a_reply_timeout_after_the_retries (real time, about 2 s)",
    101: "test_a_refused_connection_is_a_socket_error",
    103: "test_clienttcp_reads_its_settings_at_the_rising_edge",
}

PROG = """
PROGRAM MAIN
VAR
  cli : ClientTCP;
  fbA : ClientRequestReadHoldingRegisters;
  fbB : ClientRequestReadHoldingRegisters;
  fbW : ClientRequestWriteMultipleRegisters;
  fbRw : ClientRequestReadWriteMultipleRegisters;
  ip : ARRAY[0..3] OF BYTE := [127, 0, 0, 1];
  xConn, xA, xB, xW, xRw : BOOL;
  aA, aB, aRw : ARRAY[0..9] OF WORD;
  aW : ARRAY[0..9] OF WORD := [11, 22, 33];
  uiQtyA : UINT := 3;
  uiWrQty : UINT := 3;
  uiRwWrQty : UINT := 3;
  udiReply : UDINT := 50000;
  uiRetries : UINT := 0;
  udiTo : UDINT := 2000000;
  uiPort : UINT := 502;
END_VAR
cli(xConnect := xConn, aIPaddr := ip, uiPort := uiPort);
fbA(rClient := cli, xExecute := xA, uiStartItem := 5, uiQuantity := uiQtyA, pData := ADR(aA),
    udiReplyTimeout := udiReply, uiMaxRetries := uiRetries, udiTimeOut := udiTo);
fbB(rClient := cli, xExecute := xB, uiStartItem := 8, uiQuantity := 2, pData := ADR(aB));
fbW(rClient := cli, xExecute := xW, uiStartItem := 20, uiQuantity := uiWrQty, pData := ADR(aW));
fbRw(rClient := cli, xExecute := xRw, uiReadStartItem := 30, uiReadQuantity := 2,
     pReadData := ADR(aRw), uiWriteStartItem := 40, uiWriteQuantity := uiRwWrQty,
     pWriteData := ADR(aW));
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
    def make(port, timeout="1s", fc23=False):
        from mipcosim import programs as L
        src = tmp_path / "main.codesys.st"
        src.write_text(PROG)
        cfg = tmp_path / "plc.conf"
        cfg.write_text(L.outstation_config(port, channel=True, fc23=fc23)
                       .replace("timeout = 1s", f"timeout = {timeout}"))
        return Plc.build([*STANDINS, src], workdir=tmp_path / "w", compiler="stc", config=cfg)
    return make


def _connected(plc):
    plc["INST.XCONN"] = True
    plc.scan(2)
    assert plc["INST.CLI.XCONNECTED"]


def _edge(plc, var, scans=6):
    plc[f"INST.{var}"] = False
    plc.scan(1)
    plc[f"INST.{var}"] = True
    plc.scan(scans)


def test_a_read_is_done_until_xexecute_falls(build):
    srv = ModbusServer(size=3000)
    try:
        srv.holding[5:8] = [7, 8, 9]
        plc = build(srv.port)
        _connected(plc)
        _edge(plc, "XA")
        assert plc["INST.FBA.XDONE"] and not plc["INST.FBA.XBUSY"]
        assert [plc[f"INST.AA[{i}]"] for i in range(3)] == [7, 8, 9]
        plc.scan(10)                                 # xExecute held: done stays, no new request
        assert plc["INST.FBA.XDONE"] and srv.log == [(3, 5, 3)]
        plc["INST.XA"] = False
        plc.scan(1)
        assert not plc["INST.FBA.XDONE"]
    finally:
        srv.close()


def test_clienttcp_reads_its_settings_at_the_rising_edge(build):
    """aIPaddr left at the library's default 255.255.255.255 never connects: TcpConnectTimeout
    after tConnnectTimeOut (1 s). Setting the address while xConnect stays TRUE changes nothing
    (read only at the edge); the next rising edge connects."""
    srv = ModbusServer(size=3000)
    try:
        plc = build(srv.port)
        for i in range(4):
            plc[f"INST.IP[{i}]"] = 255
        plc["INST.XCONN"] = True
        plc.scan(90)
        assert not plc["INST.CLI.XCONNECTED"] and not plc["INST.CLI.XERROR"]
        plc.scan(20)                                  # 1.1 s
        assert plc["INST.CLI.XERROR"] and plc["INST.CLI.EERRORID"] == 103
        for i, b in enumerate((127, 0, 0, 1)):
            plc[f"INST.IP[{i}]"] = b
        plc.scan(5)
        assert not plc["INST.CLI.XCONNECTED"]        # no edge, no new settings
        _edge(plc, "XCONN", 2)
        assert plc["INST.CLI.XCONNECTED"] and not plc["INST.CLI.XERROR"]
        plc["INST.UIPORT"] = 0                        # port 0: no server either
        _edge(plc, "XCONN", 105)
        assert not plc["INST.CLI.XCONNECTED"] and plc["INST.CLI.EERRORID"] == 103
    finally:
        srv.close()


def test_requests_are_served_in_the_order_they_were_triggered(build):
    """fbB triggered one cycle before fbA, both waiting for the connection: B goes first,
    although A is called first in every cycle (the help: strictly in the order triggered)."""
    srv = ModbusServer(size=3000)
    try:
        plc = build(srv.port)
        plc["INST.XB"] = True
        plc.scan(1)
        plc["INST.XA"] = True
        plc["INST.XW"] = True
        plc.scan(3)
        assert srv.log == [] and plc["INST.FBA.XBUSY"] and plc["INST.FBB.XBUSY"]
        plc["INST.XCONN"] = True
        plc.scan(20)
        assert srv.log == [(3, 8, 2), (3, 5, 3), (16, 20, 3)]
        assert plc["INST.FBA.XDONE"] and plc["INST.FBB.XDONE"] and plc["INST.FBW.XDONE"]
    finally:
        srv.close()


def test_exception_replies_are_request_exception_with_the_code(build):
    srv = ScriptedServer()
    try:
        plc = build(srv.port)
        _connected(plc)
        for code in (1, 2, 3, 4, 6, 11):
            srv.exception = code
            _edge(plc, "XA")
            assert plc["INST.FBA.XERROR"] and plc["INST.FBA.EERRORID"] == 51, code
            assert plc["INST.FBA.EEXCEPTION"] == code
    finally:
        srv.close()


def test_the_modbus_limits_are_a_parameter_error_without_a_request(build):
    """Reads 1..125 (the help), FC16 1..123 and FC23's write 1..121 (the Modbus limits)."""
    srv = ScriptedServer()
    try:
        plc = build(srv.port)
        _connected(plc)
        for var, qty, fb, trig in (("UIQTYA", 0, "FBA", "XA"), ("UIQTYA", 126, "FBA", "XA"),
                                   ("UIWRQTY", 124, "FBW", "XW"), ("UIRWWRQTY", 122, "FBRW", "XRW")):
            plc[f"INST.{var}"] = qty
            _edge(plc, trig, 2)
            assert plc[f"INST.{fb}.XERROR"] and plc[f"INST.{fb}.EERRORID"] == 52, (var, qty)
        assert srv.log == []
        plc["INST.UIWRQTY"] = 123
        _edge(plc, "XW")
        assert plc["INST.FBW.XDONE"] and srv.log == [(16, 20, 123)]
    finally:
        srv.close()


def test_read_write_registers_is_one_fc23(build):
    srv = ScriptedServer()
    try:
        srv.holding[30:32] = [301, 302]
        plc = build(srv.port, fc23=True)
        _connected(plc)
        _edge(plc, "XRW")
        assert plc["INST.FBRW.XDONE"] and not plc["INST.FBRW.XERROR"]
        assert srv.log == [(23, 30, 2, 40, 3)]
        assert [plc["INST.ARW[0]"], plc["INST.ARW[1]"]] == [301, 302]
    finally:
        srv.close()


def test_a_late_reply_is_a_reply_timeout_after_the_retries(build):
    """Replies 150 ms late (real time: the runtime's master in its own thread, the server
    sleeping): with the default udiReplyTimeout of 50 ms the read ends in ReplyTimeout; with
    uiMaxRetries 2 it goes out three times (each late reply dropped) and ends the same with
    uiRetryCnt 2; with udiReplyTimeout 300 ms it is done. No request ends in a silent wait."""
    srv = ScriptedServer()
    try:
        srv.holding[5:8] = [7, 8, 9]
        srv.delay = 0.15
        plc = build(srv.port, timeout="2s")
        plc["INST.XCONN"] = True
        plc["INST.XA"] = True
        plc.run_realtime(30)                      # 300 ms
        assert plc["INST.FBA.XERROR"] and plc["INST.FBA.EERRORID"] == 56
        assert plc["INST.FBA.UIRETRYCNT"] == 0
        plc["INST.XA"] = False
        plc["INST.UIRETRIES"] = 2
        plc.run_realtime(20)                      # the late reply drained
        plc["INST.XA"] = True
        plc.run_realtime(80)
        assert plc["INST.FBA.XERROR"] and plc["INST.FBA.EERRORID"] == 56
        assert plc["INST.FBA.UIRETRYCNT"] == 2
        assert srv.count(3) == 4                  # 1 + 1 + 2 retries
        plc["INST.XA"] = False
        plc["INST.UDIREPLY"] = 300_000
        plc.run_realtime(20)
        plc["INST.XA"] = True
        plc.run_realtime(30)
        assert plc["INST.FBA.XDONE"] and plc["INST.FBA.UIRETRYCNT"] == 0
        assert [plc[f"INST.AA[{i}]"] for i in range(3)] == [7, 8, 9]
    finally:
        srv.close()


def test_a_request_while_not_connected_ends_request_not_processed(build):
    """Not connected: the request waits in the client's queue and ends with RequestNotProcessed
    when udiTimeOut (here 200 ms) runs out (our choice of the case; the help names the error)."""
    srv = ModbusServer(size=3000)
    try:
        plc = build(srv.port)
        plc["INST.UDITO"] = 200_000
        _edge(plc, "XA", 25)
        assert plc["INST.FBA.XERROR"] and plc["INST.FBA.EERRORID"] == 50
        assert srv.log == []
        _connected(plc)                          # the given-up ticket does not block the queue
        _edge(plc, "XB")
        assert plc["INST.FBB.XDONE"] and srv.log == [(3, 8, 2)]
    finally:
        srv.close()


def test_a_refused_connection_is_a_socket_error(build):
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    plc = build(port)
    _connected(plc)
    _edge(plc, "XB", 10)
    assert plc["INST.FBB.XERROR"] and plc["INST.FBB.EERRORID"] == 101


def test_a_reply_that_does_not_fit_is_an_invalid_reply(build):
    """A read of 3 registers answered with 1: the runtime's master refuses the reply (status
    1071); the stand-in gives InvalidReply (57) (the mapping is our choice; the help names the
    error "invalid / incomplete reply")."""
    srv = ScriptedServer()
    try:
        plc = build(srv.port)
        _connected(plc)
        srv.malformed = True
        _edge(plc, "XA", 10)
        assert plc["INST.FBA.XERROR"] and plc["INST.FBA.EERRORID"] == 57
    finally:
        srv.close()
