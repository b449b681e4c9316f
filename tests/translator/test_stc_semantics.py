"""stc --semantics=matiec|openplc|iec, portability warnings, and hostile input (deep nesting, unclosed
and huge comments): what a user sees on the command line and in the values the C computes."""
import os
import subprocess
import sys
import textwrap

import pytest
from mipprograms.common import config

import stc_harness as H

CONFIG = config("Main", "Main0", task="t")

# one program, the values matiec's library and C give, and the IEC 61131-3 values
DIFFERS = """PROGRAM Main
VAR
  k : DINT := 2148; k2 : DINT := 2147; t1 : TIME; t2 : TIME; tsec : TIME;
  w : DWORD := 1; n : INT := 32; sh : DWORD;
  a : INT := 30000; b : INT := 30000; avg : INT; big : BOOL;
  m : INT; ksel : INT := 7;
  cu : CTU; cv : INT; scan : INT;
  ft : F_TRIG; fq : BOOL; fcount : INT;
END_VAR
t1 := T#1ms * k;
t2 := T#1ms * k2;
tsec := T#1s * k;
sh := SHL(w, n);
avg := (a + b) / 2;
big := a + b > 32767;
m := MUX(ksel, 10, 20, 30);
scan := scan + 1;
cu(CU := (scan MOD 2) = 1, R := FALSE, PV := 2);
cv := cu.CV;
ft(CLK := FALSE);
IF ft.Q THEN fcount := fcount + 1; END_IF;
END_PROGRAM
""" + CONFIG

# (matiec's T#1ms is 999999 ns: T#1ms * 2147 = 2.146997853 s)
MATIEC = {"T1": "-2147483648", "T2": "2146997853", "TSEC": "2148000000000", "SH": "1",
          "AVG": "30000", "BIG": "1", "M": "0", "CV": "2", "FCOUNT": "1"}
IEC = {"T1": "2148000000", "T2": "2147000000", "TSEC": "2148000000000", "SH": "0",
       "AVG": "-2768", "BIG": "0", "M": "30", "CV": "5", "FCOUNT": "0"}
# OpenPLC's fork: matiec's values, but its F_TRIG gives no pulse on the first call
OPENPLC = dict(MATIEC, FCOUNT="0")


@pytest.mark.parametrize("semantics,want", [("matiec", MATIEC), ("openplc", OPENPLC), ("iec", IEC),
                                            (None, MATIEC)])
def test_values_per_semantics(tmp_path, semantics, want):
    src = tmp_path / "d.st"
    src.write_text(DIFFERS)
    exe = H.build([str(src)], str(tmp_path), semantics=semantics)
    values = H.run(exe, 10)
    got = {k: H.lookup(values, "MAIN0." + k) for k in want}
    assert got == want


def test_bad_semantics_is_usage_error(tmp_path):
    src = tmp_path / "d.st"
    src.write_text(DIFFERS)
    r = H.run_stc(["--semantics=codesys", "-o", str(tmp_path / "o"), str(src)])
    assert r.returncode == 2 and "invalid choice" in r.stderr


WARN_CASES = [
    ("t := T#1ms * k;", "TIME * number"),
    ("t := T#1ms / k;", "TIME / number"),
    ("t := t / 3;", "TIME / number"),
    ("w := SHL(w, n);", "SHL by a variable count"),
    ("w := SHR(w, 40);", "SHR of DWORD by 40"),
    ("i := (i + j) / 2;", "intermediate value of this INT"),
    ("x := i + j > 100;", "intermediate value of this INT"),
    ("i := MUX(5, i, j);", "MUX selector 5"),
    ("f(CLK := x);", "F_TRIG"),
    ("c(CU := x, PV := 3);", "CTU"),
]


def test_the_documented_time_form_is_not_warned_and_the_advice_is_that_form(tmp_path):
    """docs/wiring-openplc.md builds a TIME from milliseconds as T#1s * (n / 1000) +
    T#1ms * (n MOD 1000), exact in matiec, and says to avoid DINT_TO_TIME (matiec: seconds,
    CODESYS: milliseconds): the warning neither fires on that form nor advises DINT_TO_TIME."""
    src = tmp_path / "w.st"
    src.write_text("PROGRAM Main\nVAR t : TIME; p : WORD; k : DINT; END_VAR\n"
                   "t := T#1s * (WORD_TO_DINT(p) / 1000) + T#1ms * (WORD_TO_DINT(p) MOD 1000);\n"
                   "t := T#1ms * k;\nEND_PROGRAM\n" + CONFIG)
    r = H.run_stc(["-o", str(tmp_path / "o"), str(src)])
    assert r.returncode == 0, r.stderr
    assert f"{src}:3:" not in r.stderr, r.stderr
    warned = [x for x in r.stderr.splitlines() if x.startswith(f"{src}:4:")]
    assert len(warned) == 1 and "TIME * number" in warned[0], r.stderr
    assert "DINT_TO_TIME" not in r.stderr
    assert "T#1s * (n / 1000) + T#1ms * (n MOD 1000)" in warned[0]


@pytest.mark.parametrize("stmt,needle", WARN_CASES, ids=[n for _, n in WARN_CASES])
def test_portability_warning(tmp_path, stmt, needle):
    src = tmp_path / "w.st"
    src.write_text("PROGRAM Main\nVAR t : TIME; k : DINT; w : DWORD; n : INT; i : INT; j : INT;\n"
                   "x : BOOL; f : F_TRIG; c : CTU; END_VAR\n" + stmt + "\nEND_PROGRAM\n" + CONFIG)
    r = H.run_stc(["-o", str(tmp_path / "o"), str(src)])
    assert r.returncode == 0, r.stderr
    lines = [x for x in r.stderr.splitlines() if x.startswith(f"{src}:4:")]
    assert lines and all(": warning: portability:" in x for x in lines), r.stderr
    assert any(needle in x for x in lines), r.stderr
    # --werror-portability turns it into a failing build
    r = H.run_stc(["--werror-portability", "-o", str(tmp_path / "o2"), str(src)])
    assert r.returncode == 1 and needle in r.stderr
    assert f"{src}:4:" in r.stderr and ": error: portability:" in r.stderr
    assert not (tmp_path / "o2").exists()


def test_no_warning_for_portable_constructs(tmp_path):
    src = tmp_path / "p.st"
    src.write_text("PROGRAM Main\nVAR t : TIME; k : DINT; w : DWORD; i : INT; j : INT; END_VAR\n"
                   "t := T#1s * k; t := T#1ms * 2000; w := SHL(w, 3); i := i + j; j := i / 2;\n"
                   "t := t / 2; t := t / 512;\n"
                   "i := MUX(1, i, j);\nEND_PROGRAM\n" + CONFIG)
    r = H.run_stc(["-o", str(tmp_path / "o"), str(src)])
    assert r.returncode == 0 and r.stderr == ""


def _stc_under_limits(tmp_path, text, timeout=20):
    """Run stc in a child that reports its own peak memory (VmHWM, KiB). Not ru_maxrss: Linux
    carries the forked copy of the parent (pytest, ~340 MB late in a full run) across exec."""
    src = tmp_path / "big.st"
    src.write_text(text)
    code = textwrap.dedent(f"""
        import sys
        sys.argv = ["stc", "-o", {str(tmp_path / 'out')!r}, {str(src)!r}]
        from stc.cli import main
        rc = main()
        hwm = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:"))
        print("RC", rc, "MAXRSS", hwm, file=sys.stderr)
    """)
    env = dict(os.environ, PYTHONPATH=os.path.join(H.ROOT, "translator"))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=timeout, env=env)
    last = p.stderr.strip().splitlines()[-1].split()
    return int(last[1]), int(last[3]), p.stderr


def test_unclosed_comments_are_one_located_error_in_linear_time(tmp_path):
    # 20,000 unclosed '(*' took 43 s (quadratic comment matching)
    rc, rss, err = _stc_under_limits(tmp_path, "PROGRAM Main\nVAR x : INT; END_VAR\n" +
                                     "(* " * 20000 + "\nx := 1;\nEND_PROGRAM\n")
    assert rc == 1
    assert "big.st:3:1: error: comment '(*' is not closed: missing '*)'" in err
    assert "internal" not in err and rss < 200 * 1024


def test_unclosed_slash_comments_and_pragmas(tmp_path):
    rc, rss, err = _stc_under_limits(tmp_path, "PROGRAM Main\nVAR x : INT; END_VAR\n" +
                                     "/* { " * 20000 + "\nx := 1;\nEND_PROGRAM\n")
    assert rc == 1 and "big.st:3:1: error: comment '/*' is not closed" in err


def test_two_megabyte_comment_small_memory(tmp_path):
    # a 2 MB comment needed 765 MB
    body = "abc def ghi\n" * 180000
    rc, rss, err = _stc_under_limits(tmp_path, "(*" + body + "*)\n" + GOOD_PROGRAM)
    assert rc == 0, err
    assert rss < 200 * 1024, f"peak memory {rss} KiB"


GOOD_PROGRAM = "PROGRAM Main\nVAR x : DINT; END_VAR\nx := x + 1;\nEND_PROGRAM\n" + CONFIG


def test_long_sum_and_deep_parentheses_compile(tmp_path):
    # a sum of 350 terms or 500 nested parentheses ended in "internal: RecursionError"
    text = ("PROGRAM Main\nVAR x : DINT := 1; y : DINT; z : DINT; END_VAR\ny := " +
            " + ".join(["x"] * 350) + ";\nz := " + "(" * 500 + "x + 1" + ")" * 500 +
            ";\nEND_PROGRAM\n" + CONFIG)
    src = tmp_path / "deep.st"
    src.write_text(text)
    exe = H.build([str(src)], str(tmp_path))
    values = H.run(exe, 1)
    assert H.lookup(values, "MAIN0.Y") == "350" and H.lookup(values, "MAIN0.Z") == "2"


def test_too_deep_nesting_is_a_located_error(tmp_path):
    rc, rss, err = _stc_under_limits(tmp_path, "PROGRAM Main\nVAR x : DINT; END_VAR\nx := " +
                                     "(" * 3000 + "x" + ")" * 3000 + ";\nEND_PROGRAM\n" + CONFIG)
    assert rc == 1 and "internal" not in err
    assert "big.st:3:" in err and "nested too deeply (more than 1000 levels" in err


def test_long_statement_nesting_is_a_located_error(tmp_path):
    text = ("PROGRAM Main\nVAR x : DINT; END_VAR\n" + "IF x > 0 THEN\n" * 1200 + "x := 1;\n" +
            "END_IF;\n" * 1200 + "END_PROGRAM\n" + CONFIG)
    rc, rss, err = _stc_under_limits(tmp_path, text)
    assert rc == 1 and "internal" not in err and "nested too deeply" in err


OTHER_WARNINGS = [
    ("FUNCTION_BLOCK Acc\nVAR_IN_OUT total : INT; END_VAR\ntotal := total + 1;\n"
     "END_FUNCTION_BLOCK\nPROGRAM Main\nVAR a : Acc; s : INT; END_VAR\na(total := s);\na();\n"
     "END_PROGRAM\n", 8, 1, "VAR_IN_OUT 'TOTAL' of ACC is not passed"),
    ("PROGRAM Main\nVAR x AT %IX2000.9 : BOOL; END_VAR\nVAR y : BOOL; END_VAR\ny := x;\n"
     "END_PROGRAM\n", 2, 10, "bit number 9 is outside 0..7"),
    ("PROGRAM Main\nVAR s : STRING; END_VAR\ns := '" + "x" * 130 + "';\nEND_PROGRAM\n",
     3, 6, "string literal of 130 characters: a STRING holds 126"),
]


@pytest.mark.parametrize("text,line,col,needle", OTHER_WARNINGS,
                         ids=["in_out_missing", "bit_above_7", "long_string"])
def test_other_portability_warnings(tmp_path, text, line, col, needle):
    src = tmp_path / "w.st"
    src.write_text(text + CONFIG)
    r = H.run_stc(["-o", str(tmp_path / "o"), str(src)])
    assert r.returncode == 0, r.stderr
    assert f"{src}:{line}:{col}: warning: " in r.stderr and needle in r.stderr, r.stderr


def test_real_power_and_math_of_literals(tmp_path):
    # REAL ** was accepted but its C did not compile; TRUNC(-3.7) was rejected
    src = tmp_path / "m.st"
    src.write_text("PROGRAM Main\nVAR h : REAL; s : LREAL; d : DINT; e : REAL; END_VAR\n"
                   "h := 2.25 ** 0.5;\ns := SQRT(16.0) + EXP(0.0);\nd := TRUNC(-3.7);\n"
                   "e := EXPT(2.0, 3);\nEND_PROGRAM\n" + CONFIG)
    exe = H.build([str(src)], str(tmp_path))
    values = H.run(exe, 1)
    got = {k: H.lookup(values, "MAIN0." + k) for k in ("H", "S", "D", "E")}
    assert got == {"H": "1.5", "S": "5", "D": "-3", "E": "8"}


def test_help_documents_semantics():
    r = H.run_stc(["--help"])
    assert r.returncode == 0
    assert "--semantics" in r.stdout and "--werror-portability" in r.stdout
    assert "matiec" in r.stdout and "iec" in r.stdout
