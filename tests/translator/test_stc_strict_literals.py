"""stc --strict-iec: an untyped decimal integer literal stored in an ANY_BIT variable (BYTE,
WORD, DWORD, LWORD) is a warning, because a strict IEC 61131-3 edition-2 checker rejects it
(matiec, CODESYS and TwinCAT accept it). st_lib and the example programs of plc/ have none."""
import glob
import os

import pytest

import stc_harness as H
from mipprograms.image import program_files

PROG = """PROGRAM Main
VAR
  w : WORD;
  w2 : WORD := 5;
  b : BYTE := BYTE#5;
  d : DWORD := 16#FF;
  x : BOOL := 1;
  u : UINT := 7;
  t : TON;
END_VAR
w := 0;
w := WORD#0;
w := 16#10;
w := w AND 255;
d := 2#101;
u := 3;
x := 0;
b := 12;
IF w = 0 THEN w := WORD#1; END_IF;
END_PROGRAM
"""


def warnings(r):
    return [x for x in r.stderr.splitlines() if "strict IEC" in x]


def test_untyped_literal_into_a_bit_string_warns_with_its_place(tmp_path):
    src = tmp_path / "p.st"
    src.write_text(PROG)
    r = H.run_stc(["--strict-iec", "-o", str(tmp_path / "gen"), str(src)])
    assert r.returncode == 0, r.stderr
    got = warnings(r)
    assert got == [
        f"{src}:4:16: warning: strict IEC: initial value: untyped integer literal 5 stored in "
        f"WORD (a strict edition-2 checker rejects it): write WORD#5 or a based literal like 16#5 [W0008]",
        f"{src}:11:6: warning: strict IEC: assignment: untyped integer literal 0 stored in WORD "
        f"(a strict edition-2 checker rejects it): write WORD#0 or a based literal like 16#0 [W0008]",
        f"{src}:18:6: warning: strict IEC: assignment: untyped integer literal 12 stored in BYTE "
        f"(a strict edition-2 checker rejects it): write BYTE#12 or a based literal like 16#C [W0008]",
    ], r.stderr
    # typed and based literals, operands of an expression, BOOL and integers: no warning


def test_off_by_default_and_an_error_with_werror(tmp_path):
    src = tmp_path / "p.st"
    src.write_text(PROG)
    r = H.run_stc(["-o", str(tmp_path / "gen"), str(src)])
    assert r.returncode == 0 and not warnings(r), r.stderr
    r = H.run_stc(["--strict-iec", "--werror-portability", "-o", str(tmp_path / "gen2"), str(src)])
    assert r.returncode == 1
    assert any(": error: strict IEC: assignment:" in x for x in r.stderr.splitlines())


def test_input_argument_of_a_block_call(tmp_path):
    src = tmp_path / "p.st"
    src.write_text("FUNCTION_BLOCK FB_A\nVAR_INPUT\n  wIn : WORD;\nEND_VAR\nVAR\n  w : WORD;\nEND_VAR\n"
                   "w := wIn;\nEND_FUNCTION_BLOCK\n"
                   "PROGRAM Main\nVAR\n  a : FB_A;\nEND_VAR\na(wIn := 3);\nEND_PROGRAM\n")
    r = H.run_stc(["--strict-iec", "-o", str(tmp_path / "gen"), str(src)])
    assert r.returncode == 0, r.stderr
    assert [x.split(": warning: ")[1] for x in warnings(r)] == [
        "strict IEC: input WIN of FB_A: untyped integer literal 3 stored in WORD (a strict "
        "edition-2 checker rejects it): write WORD#3 or a based literal like 16#3 [W0008]"]


LIB = sorted(glob.glob(os.path.join(H.ROOT, "st_lib", "*", "*.st")))
PLC = ["central", "central_bidi", "central_many", "outstation", "outstation_bidi",
       "central_soe", "outstation_soe", "central_push"]


@pytest.mark.parametrize("prog", [None] + PLC)
def test_st_lib_and_plc_have_only_typed_bit_string_literals(prog, tmp_path):
    files = list(LIB)
    if prog:
        files += [os.path.join(H.ROOT, "plc", "PLC_Logger.st"),
                  os.path.join(H.ROOT, "plc", "PLC_SoeChain.st"),
                  *map(str, program_files(prog))]
    r = H.run_stc(["--strict-iec", "-o", str(tmp_path / "gen"), *files])
    assert r.returncode == 0, r.stderr[-2000:]
    assert not warnings(r), "\n".join(warnings(r))
