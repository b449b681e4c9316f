"""The MB_CLIENT stand-in (standins/s7/) against a Modbus TCP server, in virtual time (issues 36,
47): every STATUS of its table in docs/wiring-s7.md#the-stand-in is reached here, the table
below says by which test. DONE for one call, REQ as a level, the connect and disconnect phases,
MB_MODE / MB_DATA_ADDR to the function and the 0-based address on the wire, the limits, a
TCON_IP_v4 with a field left at 0 / FALSE never connecting, the inputs taken at the start of a
request, and two instances on one connection id.

| STATUS | test |
|---|---|
| 0000 | test_connect_phases_done_for_one_call_and_disconnect |
| 7001, 7002 (connect), 7001, 7002, 7003 (disconnect) | test_connect_phases_done_for_one_call_and_disconnect |
| 8086, 809B, 80B3 | test_a_connection_description_with_a_field_missing_never_connects |
| 8188, 8189, 818A, 818B, 818C, 8387 | test_parameter_errors_and_limits (8387 also test_two_instances_on_one_connection_id_get_8200) |
| 8380, 8381, 8383, 8384 | test_server_exceptions |
| 80C8 | test_no_answer_rcv_timeout_and_a_refused_connection |
| 8200 | test_two_instances_on_one_connection_id_get_8200 |
"""
import socket
import struct
import threading
from pathlib import Path

import pytest

from plcharness import Plc
from rt_helpers import ModbusServer

REPO = Path(__file__).resolve().parents[2]

STANDINS = [REPO / "standins" / "StandIn_Channel.twincat.st",
            REPO / "standins" / "s7" / "MB_CLIENT.codesys.st"]

PROG = """
PROGRAM MAIN
VAR
  mb : MB_CLIENT;
  mb2 : MB_CLIENT;
  conn : TCON_IP_v4;
  conn2 : TCON_IP_v4;
  buf : ARRAY[0..124] OF WORD;
  buf2 : ARRAY[0..124] OF WORD;
  req, req2, disc : BOOL;
  mode : USINT;
  addr : UDINT := 40006;
  nLen : UINT := 3;
  ifId : WORD := 64;
  connId : WORD := 1;
  connId2 : WORD := 2;
  ctype : BYTE := 16#0B;
  active : BOOL := TRUE;
  port : UINT := 502;
  ip1 : BYTE := 127;
  ip4 : BYTE := 1;
  rcvTimeout : REAL := 2.0;
  nDone, nError, nDone2, nError2, n7003, nBusy : UINT;
  lastStatus, lastStatus2 : WORD;
  busySt : ARRAY[0..7] OF WORD;
END_VAR
conn.InterfaceId := ifId;
conn.ID := connId;
conn.ConnectionType := ctype;
conn.ActiveEstablished := active;
conn.RemoteAddress.ADDR[1] := ip1;
conn.RemoteAddress.ADDR[4] := ip4;
conn.RemotePort := port;
conn2.InterfaceId := 64;
conn2.ID := connId2;
conn2.ConnectionType := 16#0B;
conn2.ActiveEstablished := TRUE;
conn2.RemoteAddress.ADDR[1] := 127;
conn2.RemoteAddress.ADDR[4] := 1;
conn2.RemotePort := 502;
mb.RCV_TIMEOUT := rcvTimeout;
mb(REQ := req, DISCONNECT := disc, MB_MODE := mode, MB_DATA_ADDR := addr, MB_DATA_LEN := nLen,
   MB_DATA_PTR := buf, CONNECT := conn);
IF mb.BUSY AND nBusy < 8 THEN busySt[nBusy] := mb.STATUS; nBusy := nBusy + 1; END_IF
IF mb.DONE THEN nDone := nDone + 1; lastStatus := mb.STATUS; END_IF
IF mb.ERROR THEN nError := nError + 1; lastStatus := mb.STATUS; END_IF
IF mb.STATUS = 16#7003 THEN n7003 := n7003 + 1; END_IF
mb2(REQ := req2, DISCONNECT := FALSE, MB_MODE := 0, MB_DATA_ADDR := 40009, MB_DATA_LEN := 2,
    MB_DATA_PTR := buf2, CONNECT := conn2);
IF mb2.DONE THEN nDone2 := nDone2 + 1; lastStatus2 := mb2.STATUS; END_IF
IF mb2.ERROR THEN nError2 := nError2 + 1; lastStatus2 := mb2.STATUS; END_IF
END_PROGRAM

CONFIGURATION C
RESOURCE R ON PLC
TASK t(INTERVAL := T#10ms, PRIORITY := 0);
PROGRAM inst WITH t : MAIN;
END_RESOURCE
END_CONFIGURATION
"""


class ExceptionServer(ModbusServer):
    """ModbusServer whose reads of the addresses in `exc` answer with that exception code."""

    def __init__(self, size=3000):
        self.exc = {}
        super().__init__(size)

    def _handle(self, pdu):
        addr = struct.unpack(">H", pdu[1:3])[0]
        if pdu[0] == 3 and addr in self.exc:
            with self.lock:
                self.log.append((3, addr, 0))
            return bytes([0x83, self.exc[addr]])
        return super()._handle(pdu)


def build(tmp_path, port, timeout="1s"):
    from mipcosim import programs as L
    tmp_path.mkdir(parents=True, exist_ok=True)
    src = tmp_path / "main.codesys.st"
    src.write_text(PROG)
    cfg = tmp_path / "plc.conf"
    cfg.write_text(L.outstation_config(port, channel=True).replace("timeout = 1s",
                                                                   f"timeout = {timeout}"))
    return Plc.build([*STANDINS, src], workdir=tmp_path / "w", compiler="stc", config=cfg)


def request(plc, scans=4):
    """One request: REQ for `scans` calls then FALSE; (errors, last STATUS) counted by MAIN."""
    n = plc["INST.NERROR"]
    plc["INST.REQ"] = True
    for _ in range(scans):
        plc.scan(1)
        if plc["INST.NERROR"] > n or plc["INST.MB.DONE"]:
            break
    plc["INST.REQ"] = False
    plc.scan(2)
    return plc["INST.NERROR"] - n, plc["INST.LASTSTATUS"]


@pytest.fixture
def server():
    srv = ExceptionServer()
    yield srv
    srv.close()


def test_connect_phases_done_for_one_call_and_disconnect(tmp_path, server):
    server.holding[5:8] = [7, 8, 9]
    plc = build(tmp_path, server.port)
    plc["INST.REQ"] = True
    for _ in range(6):
        plc.scan(1)
        if plc["INST.NDONE"]:
            break
    # the first request connects: 7001 in its first call, 7002 in the next, then the request
    assert [plc[f"INST.BUSYST[{i}]"] for i in range(2)] == [0x7001, 0x7002]
    assert plc["INST.MB.CONNECTED"]
    assert plc["INST.NDONE"] == 1 and plc["INST.LASTSTATUS"] == 0
    assert [plc[f"INST.BUF[{i}]"] for i in range(4)] == [7, 8, 9, 0]
    done_in = plc["INST.MB.DONE"]
    plc["INST.REQ"] = False
    plc.scan(1)
    assert done_in and not plc["INST.MB.DONE"]  # DONE was TRUE for one call only
    busy = plc["INST.NBUSY"]
    plc["INST.REQ"] = True
    plc.scan(6)
    assert plc["INST.NDONE"] >= 3               # REQ held: the requests go on, one at a time
    assert plc["INST.BUSYST[%d]" % busy] == 0   # on the open connection: no connect phase
    assert server.log[0] == (3, 5, 3)           # MB_MODE 0, 40006: FC3 at 0-based 5
    # DISCONNECT: 7001, 7002, then 7003 for one call; the next request connects again
    plc["INST.REQ"] = False
    plc.scan(2)
    plc["INST.NBUSY"] = 0
    plc["INST.DISC"] = True
    plc.scan(2)
    assert [plc[f"INST.BUSYST[{i}]"] for i in range(2)] == [0x7001, 0x7002]
    plc.scan(1)
    assert plc["INST.MB.STATUS"] == 0x7003 and not plc["INST.MB.CONNECTED"]
    plc.scan(3)
    assert plc["INST.N7003"] == 1               # 7003: one call only
    plc["INST.DISC"] = False
    plc["INST.NBUSY"] = 0
    assert request(plc, 6) == (0, 0)
    assert plc["INST.BUSYST[0]"] == 0x7001 and plc["INST.MB.CONNECTED"]


# (what the test leaves at 0 / FALSE or sets wrong, its variable, value, STATUS)
MISSING = [("InterfaceId left 0", "IFID", 0, 0x809B),
           ("InterfaceId not the CPU's", "IFID", 65, 0x809B),
           ("ID left 0", "CONNID", 0, 0x8086),
           ("ConnectionType left 0", "CTYPE", 0, 0x80B3),
           ("ConnectionType 16#11", "CTYPE", 0x11, 0x80B3),
           ("ActiveEstablished left FALSE", "ACTIVE", False, 0x80B3),
           ("RemotePort left 0", "PORT", 0, 0x80B3)]


def test_a_connection_description_with_a_field_missing_never_connects(tmp_path, server):
    plc = build(tmp_path, server.port)
    for what, var, value, status in MISSING:
        good = plc[f"INST.{var}"]
        plc[f"INST.{var}"] = value
        assert request(plc) == (1, status), what
        assert not plc["INST.MB.CONNECTED"] and server.log == [], what
        plc[f"INST.{var}"] = good
    plc["INST.IP1"] = 0
    plc["INST.IP4"] = 0
    assert request(plc) == (1, 0x80B3)         # RemoteAddress left 0.0.0.0
    plc["INST.IP1"] = 127
    plc["INST.IP4"] = 1
    assert request(plc, 6) == (0, 0) and server.log == [(3, 5, 3)]


def test_parameter_errors_and_limits(tmp_path, server):
    plc = build(tmp_path, server.port)
    for mode, addr, n, status in [(1, 40021, 1, 0x8188),     # mode 1, one register: FC6
                                  (3, 40021, 2, 0x8188),     # no such mode on the channel
                                  (0, 30001, 2, 0x8189),     # input registers
                                  (0, 40001, 0, 0x818A),
                                  (0, 40001, 126, 0x818A),   # FC3: at most 125
                                  (2, 40021, 124, 0x818A),   # FC16: at most 123
                                  (1, 40021, 124, 0x818A)]:
        plc["INST.MODE"], plc["INST.ADDR"], plc["INST.NLEN"] = mode, addr, n
        assert request(plc) == (1, status), (mode, addr, n)
    assert server.log == []
    # the limits themselves go on the wire
    for mode, addr, n, fc in [(0, 40001, 125, 3), (1, 40021, 2, 16), (2, 40021, 123, 16),
                              (2, 40021, 1, 16)]:
        plc["INST.MODE"], plc["INST.ADDR"], plc["INST.NLEN"] = mode, addr, n
        assert request(plc, 6) == (0, 0), (mode, n)
        assert server.log[-1] == (fc, addr - 40001, n)
    # the MB_DATA_PTR area: too small for MB_DATA_LEN (818B), optimized (818C)
    plc["INST.MODE"], plc["INST.ADDR"], plc["INST.NLEN"] = 0, 40006, 11
    plc["INST.MB.SI_AREAWORDS"] = 10
    assert request(plc) == (1, 0x818B)
    plc["INST.MB.SI_AREAWORDS"] = 125
    plc["INST.MB.SI_AREAOPTIMIZED"] = True
    assert request(plc) == (1, 0x818C)
    plc["INST.MB.SI_AREAOPTIMIZED"] = False
    # one connection id per instance DB: another id on the same instance, 8387
    plc["INST.CONNID"] = 3
    assert request(plc) == (1, 0x8387)
    plc["INST.CONNID"] = 1
    assert request(plc, 6) == (0, 0)


def test_inputs_changed_while_busy_do_not_change_the_running_request(tmp_path, server):
    plc = build(tmp_path, server.port)
    assert request(plc, 6) == (0, 0)            # connected
    n = len(server.log)
    plc["INST.REQ"] = True
    plc.scan(1)
    assert plc["INST.MB.BUSY"]
    plc["INST.ADDR"] = 40101                    # changed while BUSY
    plc["INST.NLEN"] = 7
    plc["INST.REQ"] = False
    for _ in range(4):
        plc.scan(1)
    assert server.log[n:] == [(3, 5, 3)]        # the request as it was taken
    assert request(plc, 6) == (0, 0) and server.log[-1] == (3, 100, 7)


def test_server_exceptions(tmp_path, server):
    server.exc = {5: 1, 6: 2, 7: 3, 8: 4}
    plc = build(tmp_path, server.port)
    for a, status in [(40006, 0x8381), (40007, 0x8383), (40008, 0x8384), (40009, 0x8380)]:
        plc["INST.ADDR"] = a
        assert request(plc, 6) == (1, status), hex(status)


def test_no_answer_rcv_timeout_and_a_refused_connection(tmp_path):
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(4)
    conns = []
    threading.Thread(target=lambda: conns.append(silent.accept()), daemon=True).start()
    try:
        plc = build(tmp_path / "silent", silent.getsockname()[1], timeout="200ms")
        assert request(plc, 60) == (1, 0x80C8)      # the wire's timeout
        assert not plc["INST.MB.CONNECTED"]         # the next request connects again
        plc["INST.RCVTIMEOUT"] = 0.05               # MB_CLIENT's own RCV_TIMEOUT first
        plc.scan(30)
        assert request(plc, 60) == (1, 0x80C8)
    finally:
        silent.close()
        for c, _ in conns:
            c.close()
    free = socket.socket()
    free.bind(("127.0.0.1", 0))
    port = free.getsockname()[1]
    free.close()                                    # nobody listens: the connection is refused
    plc = build(tmp_path / "refused", port)
    assert request(plc, 60) == (1, 0x80C8)


def test_two_instances_on_one_connection_id_get_8200(tmp_path, server):
    plc = build(tmp_path, server.port)
    plc["INST.CONNID2"] = 1                         # the mistake: the same connection id
    plc["INST.REQ"] = True
    plc["INST.REQ2"] = True
    plc.scan(5)
    assert plc["INST.NDONE"] >= 1
    assert plc["INST.NERROR2"] >= 1 and plc["INST.LASTSTATUS2"] == 0x8200
    # the instance keeps the id of its first request: another one now is 8387
    plc["INST.REQ"] = False
    plc["INST.REQ2"] = False
    plc.scan(2)
    plc["INST.CONNID2"] = 2
    plc["INST.REQ2"] = True
    plc.scan(3)
    assert plc["INST.LASTSTATUS2"] == 0x8387
    # with an id of its own from the start (a fresh instance DB) it takes its turn and is done
    plc = build(tmp_path / "own", server.port)
    plc["INST.REQ"] = True
    plc["INST.REQ2"] = True
    plc.scan(5)
    plc["INST.REQ"] = False                         # (the stand-ins share one channel: REQ
    plc.scan(8)                                     #  held would keep it; our glue drops it)
    assert plc["INST.NDONE"] >= 1 and plc["INST.NDONE2"] >= 1 and plc["INST.NERROR2"] == 0


def test_fault_injection_ends_requests_without_the_wire(tmp_path, server):
    """SI_Fail (tests only, docs/wiring-s7.md): the next SI_FailCount requests end as if the
    runtime had reported that status, mapped the way a real one is; then the wire again."""
    plc = build(tmp_path, server.port)
    assert request(plc, 6) == (0, 0)
    n = len(server.log)
    for fail, status in [(1110, 0x80C8), (1111, 0x80C8), (2, 0x8383), (0x8200, 0x8200)]:
        plc["INST.MB.SI_FAIL"] = fail
        plc["INST.MB.SI_FAILCOUNT"] = 1
        assert request(plc, 6) == (1, status), fail
        assert plc["INST.MB.SI_FAILCOUNT"] == 0
    assert len(server.log) == n
    assert request(plc, 6) == (0, 0) and len(server.log) == n + 1
