"""stc --dialect=twincat|codesys (issue 36): the ST the vendor glue is written in (pragmas,
// comments, library namespaces, STRING(n), END_IF without ';', POINTER TO, ADR, SIZEOF, p^,
MEMCPY) is read, translated and runs; the same constructs stay errors in .st files, with the
position of the construct."""

import pytest

from stc_harness import CFLAGS, translate

# one task running MAIN as instance INST (the programs below end with it)
CONFIG = """
CONFIGURATION C
RESOURCE R ON PLC
TASK t(INTERVAL := T#10ms, PRIORITY := 0);
PROGRAM inst WITH t : MAIN;
END_RESOURCE
END_CONFIGURATION
"""

PROG = """{attribute 'qualified_only'}
FUNCTION_BLOCK FB_Copy
VAR_INPUT
  pDest : POINTER TO BYTE;   // where the words go
  cb : UDINT;                // room there, in bytes
  sIP : STRING(15);
END_VAR
VAR_OUTPUT
  n : UDINT;
END_VAR
VAR
  aSrc : ARRAY[0..3] OF WORD := [1, 2, 3, 4];
  pW : POINTER TO WORD;
  iLen : INT;
END_VAR
n := Tc2_System.MEMCPY(destAddr := pDest, srcAddr := ADR(aSrc), n := MIN(cb, SIZEOF(aSrc)));
pW := pDest;
pW^ := pW^ OR 16#100;
IF n > 0 THEN
  iLen := LEN(sIP);
END_IF
END_FUNCTION_BLOCK

PROGRAM MAIN
VAR
  fb : FB_Copy;
  aDst : ARRAY[0..9] OF WORD;
  x : UDINT;
  iLen : INT;
END_VAR
fb(pDest := ADR(aDst), cb := 6, sIP := '192.168.0.10');
x := fb.n;
END_PROGRAM
""" + CONFIG


@pytest.mark.parametrize("how", ["name", "option"])
def test_vendor_constructs_translate_and_run(tmp_path, how):
    from plcharness import Plc
    src = tmp_path / ("prog.twincat.st" if how == "name" else "prog.st")
    src.write_text(PROG)
    if how == "option":
        r = translate(["--dialect=codesys", "-o", str(tmp_path / "gen"), str(src)])
        assert r.returncode == 0, r.stderr
        return
    plc = Plc.build([src], workdir=tmp_path / "w", compiler="stc")
    plc.scan(1)
    # MEMCPY copied 6 bytes (MIN of the room and SIZEOF), the pointer wrote through to aDst[0]
    assert [plc[f"INST.ADST[{i}]"] for i in range(5)] == [0x101, 2, 3, 0, 0]
    assert plc["INST.X"] == 6


def test_generated_c_compiles_without_warnings(tmp_path):
    import subprocess
    src = tmp_path / "prog.twincat.st"
    src.write_text(PROG)
    gen = tmp_path / "gen"
    r = translate(["-o", str(gen), str(src)])
    assert r.returncode == 0, r.stderr
    p = subprocess.run(["cc"] + CFLAGS + ["-I", str(gen), "-c", str(gen / "POUS.c"), "-o",
                                          str(tmp_path / "p.o")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


def refused(src, text):
    """stc on the source `text` (written to src), which it must refuse: exit 1, no traceback;
    returns (src, the CompletedProcess)."""
    src.write_text(text)
    r = translate(["-o", str(src.parent / "gen"), str(src)])
    assert r.returncode == 1
    assert "Traceback" not in r.stderr
    return src, r


@pytest.mark.parametrize("body,where,msg", [
    ("p : POINTER TO INT;", (3, 13), "POINTER TO is not portable"),
    ("x : INT := ADR(y);", (3, 12), "unknown function 'ADR'"),
    ("s : STRING(15);", None, "syntax"),
])
def test_vendor_constructs_stay_errors_in_st(tmp_path, body, where, msg):
    src, r = refused(tmp_path / "p.st",
                     f"PROGRAM Main\nVAR\n{body}\ny : INT;\nEND_VAR\ny := 1;\nEND_PROGRAM\n")
    if where:
        assert f"{src}:{where[0]}:{where[1]}: error: " in r.stderr and msg in r.stderr, r.stderr
    else:
        assert f"{src}:3:" in r.stderr, r.stderr


@pytest.mark.parametrize("body,where,msg", [
    ("y := 1;\ny^ := 2;", (7, 2), "'^' on a value of type INT, which is not a POINTER TO"),
    ("y := UDINT_TO_INT(MEMCPY(destAddr := ADR(y), srcAddr := y, n := 2));", (6, 57),
     "MEMCPY: an address (ADR(...) or a POINTER), not INT"),
    ("y := 1; {attribute 'x'", (6, 9), "unclosed pragma"),
    ("y := UDINT_TO_INT(SIZEOF(1));", (6, 26), "SIZEOF takes a variable"),
])
def test_vendor_errors_point_at_the_construct(tmp_path, body, where, msg):
    src, r = refused(tmp_path / "p.twincat.st",
                     f"PROGRAM Main\nVAR\np : POINTER TO INT;\ny : INT;\nEND_VAR\n{body}\nEND_PROGRAM\n")
    assert f"{src}:{where[0]}:{where[1]}: error: {msg}" in r.stderr, r.stderr


ENUMS = """{attribute 'qualified_only'}
TYPE Error : (OK := 0, LicenseMissing := 1, RequestException := 51, RequestParameterError,
               ReplyTimeout := 56);
END_TYPE

PROGRAM MAIN
VAR
  e : ModbusFB.Error := ModbusFB.Error.ReplyTimeout;
  w : WORD;
  n : INT;
END_VAR
w := TO_WORD(e);
e := Error.RequestParameterError;
CASE e OF
Error.OK: n := 1;
ELSE
  n := WORD_TO_INT(TO_WORD(e));
END_CASE
END_PROGRAM
""" + CONFIG


def test_codesys_enumerations_with_values_and_qualified_names(tmp_path):
    """ModbusFB's enumerations (qualified_only, explicit values, the next one +1), read as
    Enum.Value, and TO_WORD of one gives its number."""
    from plcharness import Plc
    src = tmp_path / "prog.codesys.st"
    src.write_text(ENUMS)
    plc = Plc.build([src], workdir=tmp_path / "w", compiler="stc")
    plc.scan(1)
    assert plc["INST.W"] == 56
    assert plc["INST.N"] == 52


def test_explicit_enum_values_stay_an_error_in_st(tmp_path):
    src = tmp_path / "p.st"
    src.write_text("TYPE E : (A := 0, B := 5); END_TYPE\n")
    r = translate(["-o", str(tmp_path / "gen"), str(src)])
    assert r.returncode == 1 and f"{src}:1:11: error: enumerated values with explicit" in r.stderr, r.stderr


def test_an_fb_in_out_must_be_bound_in_every_call(tmp_path):
    src = tmp_path / "p.codesys.st"
    src.write_text("""FUNCTION_BLOCK Cl
VAR_OUTPUT
  x : BOOL;
END_VAR
x := TRUE;
END_FUNCTION_BLOCK
FUNCTION_BLOCK Rq
VAR_IN_OUT
  rClient : Cl;
END_VAR
VAR_OUTPUT
  y : BOOL;
END_VAR
y := rClient.x;
END_FUNCTION_BLOCK
PROGRAM Main
VAR
  c : Cl;
  r : Rq;
END_VAR
c();
r(rClient := c);
r();
END_PROGRAM
""")
    r = translate(["-o", str(tmp_path / "gen"), str(src)])
    assert r.returncode == 1
    assert f"{src}:23:1: error: RCLIENT, a VAR_IN_OUT of RQ, must be given in every call" in r.stderr, r.stderr
