"""The TwinCAT stand-ins (standins/twincat/) against a Modbus TCP server, in virtual time:
what the manual says of FB_MBReadRegs / FB_MBWriteRegs (a rising edge starts a request, bBusy
until it has ended, bError and nErrId, cbRead, the data at pDestAddr / from pSrcAddr), and the
requests go on the wire as the program asked (the server's log)."""
import socket
import sys
import threading
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "runtime"))

from plcharness import Plc  # noqa: E402
from rt_helpers import ModbusServer  # noqa: E402

STANDINS = [REPO / "standins" / "StandIn_Channel.twincat.st",
            REPO / "standins" / "twincat" / "Tc2_ModbusSrv.twincat.st"]

PROG = """
PROGRAM MAIN
VAR
  fbRd : FB_MBReadRegs;
  fbRd2 : FB_MBReadRegs;
  fbWr : FB_MBWriteRegs;
  aRd : ARRAY[0..9] OF WORD;
  aRd2 : ARRAY[0..9] OF WORD;
  aWr : ARRAY[0..9] OF WORD := [11, 22, 33];
  bRd, bRd2, bWr : BOOL;
  nAddr : WORD := 5;
  nQty : WORD := 3;
  nScans, nBusyScans : UDINT;
END_VAR
nScans := nScans + 1;
fbRd(sIPAddr := '127.0.0.1', nUnitID := 7, nQuantity := nQty, nMBAddr := nAddr,
     cbLength := SIZEOF(aRd), pDestAddr := ADR(aRd), bExecute := bRd, tTimeout := T#1S);
fbRd2(sIPAddr := '127.0.0.1', nQuantity := 2, nMBAddr := 8,
      cbLength := SIZEOF(aRd2), pDestAddr := ADR(aRd2), bExecute := bRd2, tTimeout := T#1S);
fbWr(sIPAddr := '127.0.0.1', nQuantity := 3, nMBAddr := 20,
     cbLength := SIZEOF(aWr), pSrcAddr := ADR(aWr), bExecute := bWr, tTimeout := T#1S);
IF fbRd.bBusy THEN nBusyScans := nBusyScans + 1; END_IF
END_PROGRAM

CONFIGURATION C
RESOURCE R ON PLC
TASK t(INTERVAL := T#10ms, PRIORITY := 0);
PROGRAM inst WITH t : MAIN;
END_RESOURCE
END_CONFIGURATION
"""


def config(port, timeout="1s"):
    from mipcosim import layout as L
    return L.outstation_config(port, channel=True).replace("timeout = 1s", f"timeout = {timeout}")


@pytest.fixture
def build(tmp_path):
    sys.path.insert(0, str(REPO / "cosim"))

    def make(port, timeout="1s"):
        src = tmp_path / "main.twincat.st"
        src.write_text(PROG)
        cfg = tmp_path / "plc.conf"
        cfg.write_text(config(port, timeout))
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
