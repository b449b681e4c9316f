"""The SCL dialect (stc --dialect=scl, *.scl) and the SCL generator (stc.scl_out).

scl_accept/*.scl: TIA Portal SCL external source text (with a PROGRAM and CONFIGURATION in ST
after it to drive the blocks: TIA has OBs instead) must translate and give the
(* EXPECT path = value *) values; scl_reject/*.scl must fail with the (* ERROR line:col: msg *)
diagnostics. The generator: st_lib's SCL compiles, and an ST block and the SCL generated from
it compute the same values (the behaviour tests of st_lib on the generated SCL run in
`make scl-tests`, tests/part.mk)."""
import glob
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from mipcosim.programs import LIB_FILES
from mipprograms.common import config
from stc.scl_out import array_aliases, generate_files, library_version

import stc_harness as H

REPO = Path(H.HERE).resolve().parents[1]

ACCEPT = sorted(glob.glob(os.path.join(H.HERE, "scl_accept", "*.scl")))
REJECT = sorted(glob.glob(os.path.join(H.HERE, "scl_reject", "*.scl")))
LIB_PATHS = [str(REPO / "st_lib" / f) for f in LIB_FILES]


def _id(p):
    return os.path.splitext(os.path.basename(p))[0]


@pytest.mark.parametrize("path", ACCEPT, ids=_id)
def test_scl_accept(path, tmp_path):
    H.check_accept(path, tmp_path)


@pytest.mark.parametrize("path", REJECT, ids=_id)
def test_scl_reject(path, tmp_path):
    H.check_reject(path, tmp_path)


def test_dialect_flag_reads_any_file_name_as_scl(tmp_path):
    src = tmp_path / "block.txt"
    src.write_text('FUNCTION_BLOCK "Fb"\nVERSION : 0.1\n   VAR\n      x : Int;\n   END_VAR\n'
                   "BEGIN\n   #x := #x + 1;  // TIA comment\nEND_FUNCTION_BLOCK\n")
    as_st = H.translate(["-o", str(tmp_path / "a"), str(src)])
    assert as_st.returncode == 1 and f"{src}:1:16:" in as_st.stderr     # "Fb" is a string in ST
    as_scl = H.translate(["--dialect=scl", "-o", str(tmp_path / "b"), str(src)])
    assert as_scl.returncode == 0, as_scl.stderr


def test_st_is_read_as_before_next_to_scl(tmp_path):
    """A *.st next to a *.scl keeps the ST rules: // is still refused there."""
    st = tmp_path / "prog.st"
    st.write_text("PROGRAM Main\nVAR x : INT; END_VAR\nx := 1; // no\nEND_PROGRAM\n")
    scl = tmp_path / "fb.scl"
    scl.write_text('FUNCTION_BLOCK "Fb"\nBEGIN\n   ; // fine here\nEND_FUNCTION_BLOCK\n')
    r = H.translate(["-o", str(tmp_path / "o"), str(scl), str(st)])
    assert r.returncode == 1
    assert f"{st}:3:9: error: // comments are not portable" in r.stderr
    assert str(scl) not in r.stderr


# ---------------------------------------------------------------- the generator on st_lib

@pytest.fixture(scope="module")
def lib_scl(tmp_path_factory):
    out = tmp_path_factory.mktemp("scl")
    files = []
    for src, text in generate_files(LIB_PATHS, library_version(LIB_PATHS)).items():
        dst = out / (Path(src).stem + ".scl")
        dst.write_text(text)
        files.append(dst)
    return files


def test_every_st_lib_block_becomes_an_scl_block(lib_scl):
    blocks = set()
    for p in LIB_PATHS:
        blocks |= set(re.findall(r"^\s*(?:FUNCTION_BLOCK|FUNCTION)\s+(\w+)", Path(p).read_text(), re.M))
    text = "\n".join(f.read_text() for f in lib_scl)
    got = set(re.findall(r'^(?:FUNCTION_BLOCK|FUNCTION) "(\w+)"', text, re.M))
    assert got == blocks
    major, minor, _patch = library_version(LIB_PATHS).split(".")
    for name in blocks:
        head = re.search(rf'^(?:FUNCTION_BLOCK|FUNCTION) "{name}".*?\n(.*?)\n(.*?)\n', text, re.M)
        assert head.group(1) == "{ S7_Optimized_Access := 'TRUE' }", name
        assert head.group(2) == f"VERSION : {int(major)}.{int(minor)}", name
    # no ST type names survive: enumerations are Int, array types spelled out
    assert not re.search(r":\s*(E_MIP_\w+|MIP_T_\w+)\s*[;:]", text)
    assert "Array[0..124] of Word" in text
    assert text.count("BEGIN\n") == len(blocks)


def test_generated_st_lib_compiles_as_scl(lib_scl, tmp_path):
    r = H.translate(["--werror-portability", "-o", str(tmp_path / "o")] + [str(f) for f in lib_scl])
    assert r.returncode == 0, r.stderr


def test_array_aliases_come_from_the_types_file():
    a = array_aliases(LIB_PATHS)
    assert a["MIP_T_READBLOCK"] == "ARRAY[0..124] OF WORD"
    assert a["MIP_T_BLOCK"] == "ARRAY[0..122] OF WORD"


ROUND_TRIP_LIB = """\
TYPE
  T_Buf : ARRAY[0..3] OF WORD;
  E_Mode : (MODE_OFF, MODE_SLOW, MODE_FAST);
  T_Pair : STRUCT
    a : UINT;
    b : E_Mode := MODE_FAST; (* a PLC data type member of an enumeration *)
  END_STRUCT;
END_TYPE
FUNCTION Twice : UINT
VAR_INPUT
  u : UINT; (* the value *)
END_VAR
VAR
  tmp : UINT := 1;
END_VAR
tmp := tmp + u;
Twice := tmp * 2 - 2;
END_FUNCTION
FUNCTION_BLOCK Stepper
VAR_INPUT
  xGo : BOOL; (* steps while TRUE *)
END_VAR
VAR_OUTPUT
  xBusy : BOOL;
  xDone : BOOL;
  xError : BOOL;
  eErrorId : E_Mode;
  eMode : E_Mode := MODE_SLOW;
  aOut : T_Buf;
  uCount : UINT;
  pair : T_Pair;
END_VAR
VAR
  trig : R_TRIG;
  tWait : TON;
  i : INT;
END_VAR
(* ---- counting ---- *)
trig(CLK := xGo);
IF trig.Q THEN
  uCount := Twice(uCount + 1); (* 0, 2, 6, ... *)
END_IF;
(* ---- the mode, then the outputs ---- *)
CASE eMode OF
  MODE_SLOW: eMode := MODE_FAST;
  MODE_FAST: eMode := E_Mode#MODE_OFF;
ELSE
  eMode := MODE_SLOW;
END_CASE;
FOR i := 0 TO 3 DO
  aOut[i] := UINT_TO_WORD(uCount + INT_TO_UINT(i));
END_FOR;
tWait(IN := xGo, PT := T#30ms);
xBusy := xGo AND NOT tWait.Q;
xDone := tWait.Q;
xError := uCount > 100;
pair.a := uCount + 1;
IF xError THEN
  eErrorId := MODE_FAST;
END_IF;
END_FUNCTION_BLOCK
"""

ROUND_TRIP_PROG = """\
(* SCANS 7 *)
(* EXPECT MAIN0.CNT = 2 *)
(* EXPECT MAIN0.MODE = 2 *)
(* EXPECT MAIN0.W3 = 5 *)
(* EXPECT MAIN0.DONE = 1 *)
(* EXPECT MAIN0.PA = 3 *)
PROGRAM Main
VAR fb : Stepper; go : BOOL := TRUE; cnt : UINT; mode : INT; w3 : WORD; done : BOOL;
  pa : UINT; END_VAR
fb(xGo := go);
cnt := fb.uCount; w3 := fb.aOut[3]; done := fb.xDone; pa := fb.pair.a;
MODE_OUT
END_PROGRAM
""" + config("Main", "Main0", task="t")


def test_generated_scl_computes_what_the_st_computes(tmp_path):
    """A block with an enumeration, an array type, R_TRIG, TON, a FUNCTION with a VAR, CASE on
    the enumeration: the ST and the SCL generated from it give the same values."""
    lib = tmp_path / "lib.st"
    lib.write_text(ROUND_TRIP_LIB)
    scl_text = generate_files([str(lib)], "2.3.4")[str(lib)]
    for want in ('FUNCTION_BLOCK "Stepper"', "VERSION : 2.3", "tWait : TON_TIME;",
                 "aOut : Array[0..3] of Word;", "eMode : Int := 1 (* MODE_SLOW *);",
                 "MODE_FAST : Int := 2;", "#eMode := #MODE_OFF;", '"Twice"(#uCount + 1)',
                 "#tmp := 1;", "status : Word", "u : UInt;  // the value", 'TYPE "T_Pair"',
                 "b : Int := 2 (* MODE_FAST *);  (* a PLC data type member",
                 "    REGION counting\n", "    END_REGION\n    REGION the mode, then the outputs\n", 'pair : "T_Pair";'):
        assert want in scl_text, want
    scl = tmp_path / "lib.scl"
    scl.write_text(scl_text)
    results = {}
    st_mode = ("IF fb.eMode = MODE_OFF THEN mode := 0; ELSIF fb.eMode = MODE_SLOW THEN "
               "mode := 1; ELSE mode := 2; END_IF;")    # an enumeration has no number in ST
    for name, libfile, mode in (("st", lib, st_mode), ("scl", scl, "mode := fb.eMode;")):
        prog = tmp_path / f"prog_{name}.st"
        text = ROUND_TRIP_PROG.replace("MODE_OUT", mode)
        prog.write_text(text)
        scans, expects, sets = H.expectations(text)
        exe = H.build([str(libfile), str(prog)], str(tmp_path / name))
        values = H.run(exe, scans, sets)
        results[name] = {sym: H.lookup(values, sym) for sym, _ in expects}
        for sym, want in expects:
            assert results[name][sym] == want.replace(" ", ""), (name, sym)
    assert results["st"] == results["scl"]


def test_generator_cli_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.st"
    bad.write_text("FUNCTION_BLOCK X\nVAR a : INT END_VAR\nEND_FUNCTION_BLOCK\n")
    r = subprocess.run([sys.executable, "-m", "stc.scl_out", "-o", str(tmp_path / "o"),
                        "--version", "1.0.0", str(bad)], capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stderr.startswith(f"{bad}:2:") and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
