"""The chain's internal helpers on their own: MIP_Internal_SoeClassify (what one read of the
SIPROTEC event recorder says, judged against what MIP_SoeReader expects: MIP_SoeReader's
@behaviour, [S5] 5.2.5 in docs/chain.md) and MIP_Internal_SoeWaitReason, each as a table of
inputs -> result, compiled from st_lib and run like test_lib_internal.py's blocks."""

import pytest
from mipcosim.programs import ST_LIB, enum_values
from mipprograms.common import config

from stlib_sim import build_text, lib_type

CLS = enum_values("E_MIP_SoeReadClass", ST_LIB / "chain" / "MIP_TypesSoe.st")
STATE = enum_values("E_MIP_SoeState", ST_LIB / "chain" / "MIP_TypesSoe.st")
WAIT = enum_values("E_MIP_ChainWaitReason", ST_LIB / "chain" / "MIP_TypesSoe.st")

INPUTS = {"uSeqBits": "UINT", "xOpen": "BOOL", "wOpenSeq": "WORD", "uOpenN": "UINT",
          "xKnown": "BOOL", "wLastSeq": "WORD", "xAfterAck": "BOOL", "wAckSeq": "WORD",
          "xCand": "BOOL", "uCandN": "UINT"}
WAIT_INPUTS = ["xEnable", "xUnsaved", "xLoggerFull", "xLinkError", "xProblem"]

# the arrays as plain WORDs (matiec's VARIABLES.csv lists no arrays; see stlib_sim)
PROGRAM = f"""
PROGRAM MAIN
VAR
  aRd : {lib_type('MIP_T_SoeRegs')};
  aOp, aCd : {lib_type('MIP_T_SoeSet')};
  {", ".join(f"r{i}" for i in range(26))} : WORD;
  {", ".join(f"o{i}" for i in range(24))} : WORD;
  {", ".join(f"c{i}" for i in range(24))} : WORD;
{"".join(f"  {n} : {t};{chr(10)}" for n, t in INPUTS.items())}  eClass : {lib_type('E_MIP_SoeReadClass')};
  {", ".join(WAIT_INPUTS)} : BOOL;
  eState : {lib_type('E_MIP_SoeState')};
  eWait : {lib_type('E_MIP_ChainWaitReason')};
  cls : MIP_Internal_SoeClassify;
END_VAR
{"".join(f"aRd[{i}] := r{i};{chr(10)}" for i in range(26))}\
{"".join(f"aOp[{i}] := o{i};{chr(10)}aCd[{i}] := c{i};{chr(10)}" for i in range(24))}\
cls(aRead := aRd, aOpen := aOp, aCand := aCd,
  {", ".join(f"{n} := {n}" for n in INPUTS)});
eClass := cls.eClass;
eWait := MIP_Internal_SoeWaitReason(eState := eState,
  {", ".join(f"{n} := {n}" for n in WAIT_INPUTS)});
END_PROGRAM
""" + config("MAIN", "inst0")


@pytest.fixture(scope="module")
def plc(tmp_path_factory):
    return build_text(PROGRAM, tmp_path_factory.mktemp("stlib_internal_soe"))


def blocks(tag, n, junk):
    """n message blocks of 8 registers whose content says `tag`; the registers beyond them
    are `junk`, which no rule may look at (the read's differs from the stored sets')."""
    return [(tag << 8) + i for i in range(8 * n)] + [junk] * (24 - 8 * n)


def classify(plc, s, n, tag="A", count=None, diff=None, opened=None, cand=None, **state):
    """The class of a read with sequence number s, n blocks of content `tag` (one register
    changed at index `diff`), count entries not yet read (default n); `opened` / `cand`: (tag,
    n) of aOpen and aCand; state: the other inputs (default: 8 bits, nothing known)."""
    inputs = {"uSeqBits": 8, "xOpen": False, "wOpenSeq": 0, "uOpenN": 0, "xKnown": False,
              "wLastSeq": 0, "xAfterAck": False, "wAckSeq": 0, "xCand": False, "uCandN": 0}
    inputs.update(state)
    read = blocks(ord(tag), n, 0xEEEE)[:24]
    if diff is not None:
        read[diff] ^= 0x8000
    regs = [n if count is None else count, (n << 8) | s] + read
    open_tag, open_n = opened or ("Z", 0)
    cand_tag, cand_n = cand or ("Y", 0)
    inputs["uOpenN"] = open_n if opened else inputs["uOpenN"]
    if cand:
        inputs["xCand"], inputs["uCandN"] = True, cand_n
    values = {f"r{i}": v for i, v in enumerate(regs)}
    values.update({f"o{i}": v for i, v in enumerate(blocks(ord(open_tag), open_n, 0xDDDD))})
    values.update({f"c{i}": v for i, v in enumerate(blocks(ord(cand_tag), cand_n, 0xCCCC))})
    values.update(inputs)
    for k, v in values.items():
        plc[f"MAIN.{k}"] = v
    plc.scan()
    return {v: k for k, v in CLS.items()}[plc["MAIN.eClass"]].removeprefix("MIP_SOE_CLS_")


OPEN7 = {"xOpen": True, "wOpenSeq": 7, "opened": ("A", 2), "xKnown": True, "wLastSeq": 7}
AFTER7 = {"xAfterAck": True, "wAckSeq": 7, "opened": ("A", 2), "xKnown": True, "wLastSeq": 7}

# (what the read and the reader's state are, read: (s, n, keywords), the class)
TABLE = [
    # garbage ([S5] 5.2.4: at most 3 message blocks; our checks of the count and the number)
    ("4 blocks", (5, 4, {}), "BAD"),
    ("fewer entries (40601) than blocks", (5, 2, {"count": 1}), "BAD"),
    ("number 0 with blocks", (0, 1, {}), "BAD"),
    ("a number above 2^uSeqBits - 1", (16, 1, {"uSeqBits": 4}), "BAD"),
    ("the top number of 4 bits is one", (15, 1, {"uSeqBits": 4}), "NEW"),
    ("uSeqBits outside 2..8 counts as 8", (200, 1, {"uSeqBits": 9}), "NEW"),
    # no blocks
    ("number 0, nothing known: a relay that started", (0, 0, {}), "ZERO"),
    ("number 0 after number 0", (0, 0, {"xKnown": True}), "ZERO"),
    ("number 0 after another number: a restart", (0, 0, {"xKnown": True, "wLastSeq": 5}), "RESTART"),
    ("number 0 with a read open: a restart", (0, 0, {"xKnown": True, **OPEN7}), "RESTART"),
    ("number 0 with a read open, nothing known", (0, 0, {**OPEN7, "xKnown": False}), "ZERO"),
    ("the open read's number without blocks: acknowledged", (7, 0, {**OPEN7}), "CLOSED"),
    ("the last number without blocks", (7, 0, {"xKnown": True, "wLastSeq": 7}), "EMPTY"),
    ("any number without blocks when none is known", (9, 0, {}), "EMPTY"),
    ("entries still to come (40601) without blocks", (9, 0, {"count": 5}), "EMPTY"),
    ("another number without blocks", (9, 0, {"xKnown": True, "wLastSeq": 7}), "SEQUENCE"),
    ("number 1 without blocks is no candidate", (1, 0, {"xKnown": True, "wLastSeq": 7}), "SEQUENCE"),
    # the open read
    ("the open read again", (7, 2, {**OPEN7}), "OPEN"),
    ("the open read, more entries to come", (7, 2, {**OPEN7, "count": 9}), "OPEN"),
    ("the open read's number, one register changed", (7, 2, {**OPEN7, "diff": 15}), "CHANGED"),
    ("the open read's number, fewer blocks", (7, 1, {**OPEN7}), "CHANGED"),
    ("the open read's number, other blocks", (7, 2, {**OPEN7, "tag": "B"}), "CHANGED"),
    ("the next number: the acknowledgement was taken", (8, 1, {**OPEN7}), "NEXT"),
    ("a number after the next", (9, 1, {**OPEN7}), "SEQUENCE"),
    ("1 follows the top number", (1, 1, {**OPEN7, "wOpenSeq": 255, "wLastSeq": 255}), "NEXT"),
    ("1 follows the top of 4 bits", (1, 1, {**OPEN7, "uSeqBits": 4, "wOpenSeq": 15,
                                           "wLastSeq": 15}), "NEXT"),
    # after an acknowledgement
    ("the number acknowledged last: taken before the acknowledgement", (7, 2, {**AFTER7}), "STALE"),
    ("the number acknowledged last, other blocks", (7, 1, {**AFTER7, "tag": "B"}), "STALE"),
    ("the next number after the acknowledgement", (8, 2, {**AFTER7}), "NEW"),
    ("the last number again without an acknowledgement", (7, 2, {"xKnown": True, "wLastSeq": 7}), "SEQUENCE"),
    ("the next number", (8, 3, {"xKnown": True, "wLastSeq": 7, "count": 40}), "NEW"),
    ("the next number after the top", (1, 3, {"xKnown": True, "wLastSeq": 255}), "NEW"),
    ("any number when none is known", (42, 1, {}), "NEW"),
    ("a number going backwards", (3, 1, {"xKnown": True, "wLastSeq": 7}), "SEQUENCE"),
    # number 1 with blocks, rejected: a restarted relay's first read? (docs/chain.md "Restarts")
    ("1 out of sequence: the candidate", (1, 1, {"xKnown": True, "wLastSeq": 5}), "CAND_SEQUENCE"),
    ("1 out of sequence twice: a restarted relay", (1, 1, {"xKnown": True, "wLastSeq": 5,
                                                          "cand": ("A", 1)}), "RESTARTED"),
    ("1 again with other registers: a new candidate", (1, 1, {"xKnown": True, "wLastSeq": 5,
                                                             "cand": ("A", 1), "diff": 3}), "CAND_SEQUENCE"),
    ("1 again with another block count", (1, 2, {"xKnown": True, "wLastSeq": 5,
                                                 "cand": ("A", 1)}), "CAND_SEQUENCE"),
    ("open read 1 changed: the candidate", (1, 2, {**OPEN7, "wOpenSeq": 1, "wLastSeq": 1,
                                                   "tag": "B"}), "CAND_CHANGED"),
    ("open read 1 changed twice: a restarted relay", (1, 2, {**OPEN7, "wOpenSeq": 1, "wLastSeq": 1,
                                                             "tag": "B", "cand": ("B", 2)}), "RESTARTED"),
    ("1 acknowledged, other registers: the candidate", (1, 2, {**AFTER7, "wAckSeq": 1, "wLastSeq": 1,
                                                               "tag": "B"}), "CAND_STALE"),
    ("1 acknowledged, other registers twice: a restarted relay",
     (1, 2, {**AFTER7, "wAckSeq": 1, "wLastSeq": 1, "tag": "B", "cand": ("B", 2)}), "RESTARTED"),
    ("1 acknowledged, its own image: stale, never a candidate",
     (1, 2, {**AFTER7, "wAckSeq": 1, "wLastSeq": 1, "cand": ("A", 2)}), "STALE"),
    ("2 out of sequence is no candidate", (2, 1, {"xKnown": True, "wLastSeq": 5,
                                                  "cand": ("A", 1)}), "SEQUENCE"),
    ("1 in sequence is a new read, not a candidate", (1, 1, {"xKnown": True, "wLastSeq": 255,
                                                            "cand": ("A", 1)}), "NEW"),
]


@pytest.mark.parametrize("what,read,want", TABLE, ids=[t[0] for t in TABLE])
def test_classify(plc, what, read, want):
    s, n, kw = read
    assert classify(plc, s, n, **kw) == want


def test_the_table_reaches_every_class():
    assert {t[2] for t in TABLE} == {k.removeprefix("MIP_SOE_CLS_") for k in CLS}


# (eState, the inputs that are TRUE, eWaitReason): MIP_SoeReader's diagnostics
WAIT_TABLE = [
    ("DISABLED", {"xUnsaved", "xLoggerFull", "xLinkError", "xProblem"}, "NONE"),
    ("ERROR", {"xEnable", "xUnsaved", "xLinkError"}, "NONE"),
    ("ACK", {"xEnable", "xUnsaved", "xLoggerFull"}, "SNAPSHOT"),
    ("VERIFY", {"xEnable", "xUnsaved"}, "SNAPSHOT"),
    ("DELIVER", {"xEnable", "xUnsaved"}, "STORED"),
    ("ACK", {"xEnable", "xLoggerFull", "xLinkError"}, "WRITE"),
    ("RETRY", {"xEnable", "xUnsaved", "xLoggerFull"}, "RETRY"),
    ("VERIFY", {"xEnable", "xLoggerFull"}, "VERIFY"),
    ("READ", {"xEnable", "xLoggerFull", "xLinkError", "xProblem"}, "LOGGER_FULL"),
    ("DELIVER", {"xEnable", "xLoggerFull"}, "LOGGER_FULL"),
    ("DELIVER", {"xEnable", "xLinkError", "xProblem"}, "STORED"),
    ("READ", {"xEnable", "xLinkError", "xProblem"}, "LINK"),
    ("READ", {"xEnable", "xProblem"}, "CHECK"),
    ("READ", {"xEnable"}, "READ"),
]


@pytest.mark.parametrize("state,true,want", WAIT_TABLE)
def test_wait_reason(plc, state, true, want):
    plc["MAIN.eState"] = STATE["MIP_SOE_" + state]
    for name in WAIT_INPUTS:
        plc[f"MAIN.{name}"] = name in true
    plc.scan()
    assert plc["MAIN.eWait"] == WAIT["MIP_CHAIN_WAIT_" + want]
