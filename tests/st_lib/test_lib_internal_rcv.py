"""MIP_Receiver's internal helpers on their own: MIP_Internal_RcvClassify (what a record
number read is against the number acknowledged last: PROTOCOL.md P15 .. P21) as a table of
reads -> classes, MIP_Internal_ReadCheck (the check value it compares, P17) and
MIP_Internal_AckBlock (the acknowledgement and its echo, P24), compiled from st_lib and run
like test_lib_internal.py's blocks."""

import random

import pytest
from mipcosim.programs import enum_values
from mipprograms.common import config

from stlib_sim import build_text, lib_type
from test_lib_interop import MAGIC, check

CLS = enum_values("E_MIP_RcvClass")
NAMES = {v: k.removeprefix("MIP_RCV_CLS_") for k, v in CLS.items()}
FFFF = 0xFFFF

CLS_INPUTS = {"uNum": "UINT", "uL": "UINT", "uCount": "UINT", "wSumNow": "WORD", "wSum": "WORD",
              "xNewTelegram": "BOOL", "xLoneBlock": "BOOL", "xFirstLast": "BOOL",
              "wFirstSum": "WORD"}
ACK_INPUTS = {"wAck": "WORD", "wAckSum": "WORD", "uStream": "UINT", "uHeader": "UINT",
              "xBidi": "BOOL", "xStatic": "BOOL"}

# the arrays as plain WORDs (matiec's VARIABLES.csv lists no arrays; see stlib_sim)
PROGRAM = f"""
PROGRAM MAIN
VAR
  aRd : {lib_type('MIP_T_ReadBlock')};
  aWr : {lib_type('MIP_T_Block')};
  {", ".join(f"r{i}" for i in range(125))} : WORD;
  w0, w1, w2, w3, wCheck : WORD;
  uChkCount, uOther, uWriteLen : UINT;
  xChkBidi, xRestZero : BOOL;
{"".join(f"  {n} : {t};{chr(10)}" for n, t in {**CLS_INPUTS, **ACK_INPUTS}.items())}\
  eCls : {lib_type('E_MIP_RcvClass')};
  chk : MIP_Internal_ReadCheck;
  ack : MIP_Internal_AckBlock;
  i : UINT;
END_VAR
{"".join(f"aRd[{i}] := r{i};{chr(10)}" for i in range(125))}\
eCls := MIP_Internal_RcvClassify({", ".join(f"{n} := {n}" for n in CLS_INPUTS)});
chk(aRead := aRd, uCount := uChkCount, xBidi := xChkBidi, uOther := uOther);
wCheck := chk.wCheck;
FOR i := 0 TO 122 DO
  aWr[i] := WORD#16#FFFF;   (* junk the block must clear *)
END_FOR;
ack(aWrite := aWr, {", ".join(f"{n} := {n}" for n in ACK_INPUTS)});
uWriteLen := ack.uWriteLen;
w0 := aWr[0];
w1 := aWr[1];
w2 := aWr[2];
w3 := aWr[3];
xRestZero := TRUE;
FOR i := 4 TO 122 DO
  IF aWr[i] <> WORD#0 THEN
    xRestZero := FALSE;
  END_IF;
END_FOR;
END_PROGRAM
""" + config("MAIN", "inst0")


@pytest.fixture(scope="module")
def plc(tmp_path_factory):
    return build_text(PROGRAM, tmp_path_factory.mktemp("stlib_internal_rcv"))


def run(plc, **values):
    for k, v in values.items():
        plc[f"MAIN.{k}"] = v
    plc.scan()


def classify(plc, num, last, same=False, count=5, new=True, lone_block=False, first_last=None):
    """The class of record number `num` read with L = `last`; `same`: the block's check value
    is the accepted record's; first_last: None, or whether the first block's 16#FFFF had this
    block's check value."""
    run(plc, uNum=num, uL=last, uCount=count, wSumNow=0x1234, wSum=0x1234 if same else 0x4321,
        xNewTelegram=new, xLoneBlock=lone_block, xFirstLast=first_last is not None,
        wFirstSum=0x1234 if first_last else 0x5555)
    return NAMES[plc["MAIN.eCls"]]


# (what, (num, L, keywords), class)
TABLE = [
    # P16: record 0, whatever was open
    ("0 with nothing open", (0, 0, {}), "ZERO"),
    ("0 mid-transfer", (0, 7, {}), "ZERO"),
    ("0 after a complete transfer", (0, FFFF, {"same": True}), "ZERO"),
    # P17: L again with the same content
    ("a duplicate", (7, 7, {"same": True}), "DUPLICATE"),
    ("a duplicate read again (no new telegram)", (7, 7, {"same": True, "new": False}), "DUPLICATE"),
    ("a duplicate longer than 123 registers", (7, 7, {"same": True, "count": 124}), "DUPLICATE"),
    ("record 1 again, same content", (1, 1, {"same": True}), "DUPLICATE"),
    ("16#FFFF again, same content", (FFFF, FFFF, {"same": True}), "DUPLICATE"),
    # P15: the next one
    ("1 after 0", (1, 0, {}), "NEXT"),
    ("1 after a complete transfer", (1, FFFF, {}), "NEXT"),
    ("L + 1", (8, 7, {}), "NEXT"),
    ("16#FFFF after 7", (FFFF, 7, {}), "NEXT"),
    ("65534 after 65533", (65534, 65533, {}), "NEXT"),
    ("16#FFFF after 65534", (FFFF, 65534, {}), "NEXT"),
    ("16#FFFF after 1", (FFFF, 1, {}), "NEXT"),
    # P18: record 1 while a transfer is open
    ("1 mid-transfer", (1, 7, {}), "RESTART"),
    ("1 after 65534", (1, 65534, {}), "RESTART"),
    ("1 again with other content", (1, 1, {}), "RESTART"),
    # P19: a lone 16#FFFF
    ("a lone 16#FFFF with nothing open", (FFFF, 0, {}), "NEXT"),
    ("a lone 16#FFFF after a complete transfer", (FFFF, FFFF, {}), "NEXT"),
    ("a lone 16#FFFF read again (no new telegram)", (FFFF, 0, {"new": False}), "STRAY"),
    ("a lone 16#FFFF after a complete one, read again", (FFFF, FFFF, {"new": False}), "OTHER"),
    ("a lone 16#FFFF that may end a lost transfer", (FFFF, 0, {"lone_block": True}), "STRAY"),
    ("a lone 16#FFFF after a complete one, lost transfer", (FFFF, FFFF, {"lone_block": True}), "OTHER"),
    ("the first block's old 16#FFFF", (FFFF, 0, {"first_last": True}), "STRAY"),
    ("another 16#FFFF than the first block's old one", (FFFF, 0, {"first_last": False}), "NEXT"),
    ("a lone 16#FFFF longer than 123 registers", (FFFF, 0, {"count": 124}), "OTHER"),
    # P20: everything else
    ("L with other content", (7, 7, {}), "OTHER"),
    ("the next one longer than 123 registers", (8, 7, {"count": 124}), "OTHER"),
    ("a number skipped", (9, 7, {}), "STRAY"),
    ("a number going back", (6, 7, {}), "STRAY"),
    ("a first block mid-transfer", (6, 0, {}), "STRAY"),
    ("2 after a complete transfer", (2, FFFF, {}), "STRAY"),
    ("65535 - 1 after 65534 is no wrap", (65534, 65534, {}), "OTHER"),
]


@pytest.mark.parametrize("what,read,want", TABLE, ids=[t[0] for t in TABLE])
def test_classify(plc, what, read, want):
    num, last, kw = read
    assert classify(plc, num, last, **kw) == want


def test_the_table_reaches_every_class():
    assert {t[2] for t in TABLE} == set(NAMES.values())


def read_check(plc, regs, count, bidi=False, other=0):
    values = {f"r{i}": 0 for i in range(125)}
    values.update({f"r{i + 2}": v for i, v in enumerate(regs)})
    values["r1"] = count
    run(plc, uChkCount=count, xChkBidi=bidi, uOther=other, **values)
    return plc["MAIN.wCheck"]


def test_read_check_is_the_check_value_of_the_block(plc):
    rnd = random.Random(17)
    for n in (0, 1, 2, 57, 123):
        regs = [rnd.randrange(0x10000) for _ in range(n)]
        assert read_check(plc, regs, n) == check(regs), n


def test_read_check_leaves_out_the_other_streams_counter_and_what_is_beyond_123(plc):
    rnd = random.Random(5)
    regs = [rnd.randrange(0x10000) for _ in range(123)]
    base = read_check(plc, regs, 40, bidi=True, other=1)
    assert base != read_check(plc, regs, 40)              # register 1 is left out ...
    assert read_check(plc, [regs[0] ^ 1] + regs[1:], 40, bidi=True, other=1) == base
    assert read_check(plc, [regs[0] ^ 1] + regs[1:], 40) != read_check(plc, regs, 40)
    assert read_check(plc, regs[:1] + [regs[1] ^ 1] + regs[2:], 40, bidi=True, other=1) != base
    # ... and a register beyond the count or beyond 123 never counts
    assert read_check(plc, regs[:40] + [0] * 83, 40, bidi=True, other=1) == base
    assert read_check(plc, regs, 124) != read_check(plc, regs, 123)   # the count itself counts


# (what, inputs, (uWriteLen, [w0, w1, w2, w3]))
ACK_TABLE = [
    ("acknowledgement 0: the echo", dict(wAck=0, wAckSum=0xBEEF), (3, [0, MAGIC, 0xBEEF, 0])),
    ("acknowledgement 1: the echo", dict(wAck=1, wAckSum=0x1234), (3, [1, MAGIC, 0x1234, 0])),
    ("acknowledgement 2: the note's block", dict(wAck=2, wAckSum=0x1234), (1, [2, 0, 0, 0])),
    ("16#FFFF: the note's block", dict(wAck=FFFF, wAckSum=0x1234), (1, [FFFF, 0, 0, 0])),
    ("static mode clears the echo", dict(wAck=2, wAckSum=0x1234, xStatic=True), (3, [2, 0, 0, 0])),
    ("static mode, acknowledgement 1", dict(wAck=1, wAckSum=0x77, xStatic=True), (3, [1, MAGIC, 0x77, 0])),
    ("bidirectional, outstation stream", dict(wAck=1, wAckSum=0x77, xBidi=True, uStream=0, uHeader=2),
     (2, [1, 0, 0, 0])),
    ("bidirectional, central stream", dict(wAck=5, xBidi=True, uStream=1, uHeader=2), (2, [0, 5, 0, 0])),
]


@pytest.mark.parametrize("what,inputs,want", ACK_TABLE, ids=[t[0] for t in ACK_TABLE])
def test_ack_block(plc, what, inputs, want):
    values = dict(wAck=0, wAckSum=0, uStream=0, uHeader=1, xBidi=False, xStatic=False)
    values.update(inputs)
    run(plc, **values)
    got = (plc["MAIN.uWriteLen"], [plc[f"MAIN.w{i}"] for i in range(4)])
    assert got == want and plc["MAIN.xRestZero"]
