"""MIP_Sender's internal blocks on their own (issue 46): the W1 snapshot gate
(MIP_Internal_SnapshotGate, also MIP_SoeServer's) and the window 2 operations
(MIP_Internal_Window, PROTOCOL.md P27): when a held record may go, and when the window
opens again after going back. The sender's behaviour with them runs in test_lib_window*.py and
test_lib_warm.py."""
import pytest
from mipprograms.common import config

from stlib_sim import build_text, enum_values

OP = enum_values("E_MIP_Internal_WindowOp")
WIN = enum_values("E_MIP_WindowState")

PROGRAM = """
PROGRAM MAIN
VAR
  gate : MIP_Internal_SnapshotGate;
  win : MIP_Internal_Window;
  xGate, xArm, xRetained : BOOL;
  wSnapshots : WORD;
  xWin : BOOL;
  eOp : E_MIP_Internal_WindowOp;
  xAckValid, xEcho, xNewTelegram, xWriteIdle : BOOL;
  wAck, wAheadNext, wFirst : WORD;
  uBlockLen : UINT;
  aBlock : MIP_T_Block;
  wHeld : WORD;
END_VAR
IF xGate THEN
  gate(xArm := xArm, xRetained := xRetained, wSnapshots := wSnapshots);
END_IF;
IF xWin THEN
  aBlock[0] := wFirst;
  win(eOp := eOp, xAckValid := xAckValid, wAck := wAck, xEcho := xEcho,
      xNewTelegram := xNewTelegram, xWriteIdle := xWriteIdle, aBlock := aBlock,
      uBlockLen := uBlockLen, wAheadNext := wAheadNext);
END_IF;
wHeld := win.aHold[0];
END_PROGRAM
""" + config("MAIN", "inst0")


@pytest.fixture
def plc(tmp_path):
    return build_text(PROGRAM, tmp_path)     # built once, a fresh instance per test


def gate(plc, arm, retained=True, snapshots=None):
    plc["MAIN.xGate"], plc["MAIN.xWin"] = True, False
    plc["MAIN.xArm"], plc["MAIN.xRetained"] = arm, retained
    if snapshots is not None:
        plc["MAIN.wSnapshots"] = snapshots
    plc.scan()
    return plc["MAIN.gate.xUnsaved"]


def test_gate_holds_a_new_state_until_the_snapshot_count_changes(plc):
    assert gate(plc, True, snapshots=4)            # noted at count 4
    assert gate(plc, False)                        # no snapshot completed since
    assert gate(plc, False, snapshots=4)
    assert not gate(plc, False, snapshots=5)       # one completed: it holds the state
    assert not gate(plc, False, snapshots=6)


def test_gate_a_new_state_in_the_scan_a_snapshot_completes_waits_for_the_next(plc):
    assert gate(plc, True, snapshots=1)
    assert gate(plc, True, snapshots=2)            # noted again, at 2: the snapshot 2 may not hold it
    assert gate(plc, False)
    assert not gate(plc, False, snapshots=3)


def test_gate_open_at_once_without_retain(plc):
    assert not gate(plc, True, retained=False, snapshots=1)
    assert not gate(plc, False)


def win(plc, op, **inputs):
    plc["MAIN.xGate"], plc["MAIN.xWin"] = False, True
    plc["MAIN.eOp"] = OP[op]
    for k, v in inputs.items():
        plc[f"MAIN.{k}"] = v
    plc.scan()
    return {k: plc[f"MAIN.win.{k}"] for k in ("eWindow", "xOpen", "xAckAhead", "wAheadRec",
                                                "uHoldLen", "xFreshAhead")} | {"held": plc["MAIN.wHeld"]}


def read(plc, ack, echo=False, new=True, idle=True):
    return win(plc, "MIP_WOP_READ", xAckValid=True, wAck=ack, xEcho=echo, xNewTelegram=new,
               xWriteIdle=idle)


def test_window_ahead_holds_the_record_in_flight_and_counts_the_later_acknowledgement(plc):
    s = win(plc, "MIP_WOP_START")
    assert s["eWindow"] == WIN["MIP_WIN_SINGLE"] and s["xOpen"]
    s = win(plc, "MIP_WOP_AHEAD", wFirst=3, uBlockLen=10, wAheadNext=4)   # 3 in flight, 4 ahead
    assert s["eWindow"] == WIN["MIP_WIN_AHEAD"] and not s["xOpen"]
    assert (s["held"], s["uHoldLen"], s["wAheadRec"]) == (3, 10, 4)
    assert not read(plc, 3)["xAckAhead"]                  # the older one: the caller's own match
    assert not read(plc, 4, echo=True)["xAckAhead"]       # an echo is never the record ahead's
    s = read(plc, 4)
    assert s["xAckAhead"] and s["xFreshAhead"]            # a telegram after the write ahead
    s = win(plc, "MIP_WOP_ACKED_BOTH")
    assert s["eWindow"] == WIN["MIP_WIN_SINGLE"] and s["xOpen"]
    assert not read(plc, 4)["xAckAhead"]                  # single: nothing ahead


def test_window_going_back_pauses_for_eight_acknowledged_records(plc):
    win(plc, "MIP_WOP_START")
    win(plc, "MIP_WOP_AHEAD", wFirst=5, uBlockLen=7, wAheadNext=6)
    s = win(plc, "MIP_WOP_BACK", wFirst=6, uBlockLen=9)   # the caller writes 5 again, holds 6
    assert s["eWindow"] == WIN["MIP_WIN_BACK"] and (s["held"], s["uHoldLen"]) == (6, 9)
    win(plc, "MIP_WOP_ACKED")                             # 5 acknowledged: 6 goes out again
    s = win(plc, "MIP_WOP_SINGLE")
    assert s["eWindow"] == WIN["MIP_WIN_SINGLE"] and not s["xOpen"]
    for _ in range(6):
        assert not win(plc, "MIP_WOP_ACKED")["xOpen"]
    assert win(plc, "MIP_WOP_ACKED")["xOpen"]             # the 8th acknowledged record


def test_window_back_while_single_changes_nothing(plc):
    win(plc, "MIP_WOP_START")
    s = win(plc, "MIP_WOP_BACK", wFirst=1, uBlockLen=2)
    assert s["eWindow"] == WIN["MIP_WIN_SINGLE"] and s["xOpen"]
