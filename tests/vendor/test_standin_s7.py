"""The MB_CLIENT stand-in (standins/s7/) against a Modbus TCP server, in virtual time: DONE for
one call, REQ as a level (one request at a time per instance), MB_MODE / MB_DATA_ADDR to the
function and the 0-based address on the wire, the STATUS codes of the manual, and two instances
on one connection id: the second gets 16#8200 (the connection is busy), not a wait."""
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "runtime"))

from plcharness import Plc  # noqa: E402
from rt_helpers import ModbusServer  # noqa: E402

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
  req, req2 : BOOL;
  mode : USINT;
  addr : UDINT := 40006;
  nLen : UINT := 3;
  nDone, nError, nDone2, nError2 : UINT;
  lastStatus, lastStatus2 : WORD;
END_VAR
conn.ID := 1;
mb(REQ := req, DISCONNECT := FALSE, MB_MODE := mode, MB_DATA_ADDR := addr, MB_DATA_LEN := nLen,
   MB_DATA_PTR := buf, CONNECT := conn);
IF mb.DONE THEN nDone := nDone + 1; lastStatus := mb.STATUS; END_IF
IF mb.ERROR THEN nError := nError + 1; lastStatus := mb.STATUS; END_IF
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


def build(tmp_path, port):
    sys.path.insert(0, str(REPO / "cosim"))
    from mipcosim import layout as L
    src = tmp_path / "main.codesys.st"
    src.write_text(PROG)
    cfg = tmp_path / "plc.conf"
    cfg.write_text(L.outstation_config(port, channel=True))
    return Plc.build([*STANDINS, src], workdir=tmp_path / "w", compiler="stc", config=cfg)


def test_done_for_one_call_and_req_as_a_level(tmp_path):
    srv = ModbusServer(size=3000)
    try:
        srv.holding[5:8] = [7, 8, 9]
        plc = build(tmp_path, srv.port)
        plc["INST.REQ"] = True
        for _ in range(5):
            plc.scan(1)
            if plc["INST.NDONE"]:
                break
        assert plc["INST.NDONE"] == 1 and plc["INST.LASTSTATUS"] == 0
        assert [plc[f"INST.BUF[{i}]"] for i in range(4)] == [7, 8, 9, 0]
        done_in = plc["INST.MB.DONE"]
        plc["INST.REQ"] = False
        plc.scan(1)
        assert done_in and not plc["INST.MB.DONE"]  # DONE was TRUE for one call only
        plc["INST.REQ"] = True
        plc.scan(6)
        assert plc["INST.NDONE"] >= 3               # REQ held: the requests go on, one at a time
        assert srv.log[0] == (3, 5, 3)              # MB_MODE 0, 40006: FC3 at 0-based 5
        plc["INST.REQ"] = False
        plc.scan(3)
        n = len(srv.log)
        plc["INST.MODE"] = 2                        # MB_MODE 2: FC16, also for one register
        plc["INST.NLEN"] = 1
        plc["INST.ADDR"] = 40021
        plc["INST.BUF[0]"] = 4711
        plc["INST.REQ"] = True
        plc.scan(2)
        plc["INST.REQ"] = False
        plc.scan(2)
        assert srv.log[n] == (16, 20, 1) and srv.holding[20] == 4711
        # MB_MODE 1 with one register would be FC6: refused as an invalid mode (not on the channel)
        plc["INST.MODE"] = 1
        plc["INST.REQ"] = True
        plc.scan(1)
        plc["INST.REQ"] = False
        assert plc["INST.LASTSTATUS"] == 0x8188
        # exception 02 of the server: 16#8383
        plc["INST.MODE"] = 0
        plc["INST.ADDR"] = 42999
        plc["INST.NLEN"] = 3
        plc.scan(2)
        plc["INST.REQ"] = True
        plc.scan(3)
        plc["INST.REQ"] = False
        assert plc["INST.LASTSTATUS"] == 0x8383
    finally:
        srv.close()


def test_two_instances_on_one_connection_id_get_8200(tmp_path):
    srv = ModbusServer(size=3000)
    try:
        plc = build(tmp_path, srv.port)
        plc["INST.CONN2.ID"] = 1                    # the mistake: the same connection id
        plc["INST.REQ"] = True
        plc["INST.REQ2"] = True
        plc.scan(3)
        assert plc["INST.NDONE"] >= 1
        assert plc["INST.NERROR2"] >= 1 and plc["INST.LASTSTATUS2"] == 0x8200
        # with an id of its own it takes its turn and is done
        plc["INST.REQ"] = False
        plc["INST.REQ2"] = False
        plc.scan(2)
        plc["INST.CONN2.ID"] = 2
        plc["INST.REQ"] = True
        plc["INST.REQ2"] = True
        plc.scan(6)
        assert plc["INST.NDONE2"] >= 1 and plc["INST.LASTSTATUS2"] == 0
    finally:
        srv.close()
