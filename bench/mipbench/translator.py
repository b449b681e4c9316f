"""Figure 5: the translator's speed (a generated program through stc; translator/bench_stc.py)."""
from __future__ import annotations

import re
import subprocess
import tempfile
import time

from .common import BUILD, BenchError, PY, REPO, STC, error, line, run

# ---------------------------------------------------------------- 5. translator, memory

def gen_st(lines_wanted: int) -> str:
    """A program of about lines_wanted lines: FBs with arithmetic, IF/CASE-free control flow,
    loops and calls, in the matiec dialect the translator accepts."""
    out = []
    k = 0
    while len(out) < lines_wanted - 30:
        out += [f"FUNCTION_BLOCK FB{k}",
                "VAR_INPUT", "  xIn : BOOL;", "  wIn : WORD;", "  iIn : INT;", "END_VAR",
                "VAR_OUTPUT", "  wOut : WORD;", "  iOut : INT;", "  xOut : BOOL;", "END_VAR",
                "VAR", "  aBuf : ARRAY[0..15] OF WORD;", "  i : INT;", "  t : TON;", "END_VAR",
                "IF xIn AND (wIn <> 16#0000) THEN",
                f"  iOut := iIn * {k % 7 + 2} + INT#{k % 100};",
                "ELSIF NOT xIn THEN", "  iOut := iIn - 1;", "ELSE", "  iOut := 0;", "END_IF;",
                "FOR i := 0 TO 15 DO",
                "  aBuf[i] := wIn XOR INT_TO_WORD(i);", "END_FOR;",
                "wOut := aBuf[3] OR SHL(wIn, 2);",
                "t(IN := xIn, PT := T#100ms);",
                "xOut := t.Q OR (iOut > 100);",
                "END_FUNCTION_BLOCK", ""]
        k += 1
    n = k
    prog = ["PROGRAM MAIN", "VAR"] + [f"  f{i} : FB{i};" for i in range(n)] + \
           ["  u : UINT;", "  x : BOOL;", "END_VAR"]
    prog += [f"f{i}(xIn := x, wIn := UINT_TO_WORD(u), iIn := {i});" for i in range(n)]
    prog += ["x := NOT x;", "u := u + 1;", "END_PROGRAM", "",
             "CONFIGURATION Config0", "  RESOURCE Res0 ON PLC",
             "    TASK tMain(INTERVAL := T#10ms, PRIORITY := 0);",
             "    PROGRAM inst0 WITH tMain : MAIN;", "  END_RESOURCE", "END_CONFIGURATION", ""]
    return "\n".join(out + prog)


def fig_translator(quick):
    name = "translator_speed"
    target_lines = 5000
    reps = 1 if quick else 3
    src = BUILD / "gen5000.st"
    text = gen_st(target_lines)
    src.write_text(text)
    nlines = text.count("\n")
    try:
        with tempfile.TemporaryDirectory(dir=BUILD) as d:
            run([STC, "-o", d, src])       # warm-up, untimed: stc's grammar cache, page cache
        import resource
        times, cpus = [], []
        for _ in range(reps):
            with tempfile.TemporaryDirectory(dir=BUILD) as d:
                r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                run([STC, "-o", d, src])
                times.append(time.perf_counter() - t0)
                r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpus.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    except (BenchError, subprocess.SubprocessError, OSError) as e:
        error(name, str(e))
        return
    t = min(times)
    r = nlines / t
    cpu = min(cpus)
    line(name, f"{r:.0f} lines/s ({nlines} lines in {t:.2f} s wall, {cpu:.2f} s CPU: "
         f"{nlines / cpu if cpu else 0:.0f} lines per CPU second; the whole stc process "
         f"incl. Python start-up, after one untimed warm-up run, best of {reps}; "
         f"{r / 5000:.2f} of target >= 5000 lines/s)",
         "OK" if r >= 5000 else "MISSED")


def fig_translator_inprocess(quick):
    """The translator's own benchmark (translator/bench_stc.py: its generated ~5,000-line file,
    in-process, grammar loaded once), reported next to the whole-process figure above."""
    name = "translator_speed_inprocess"
    script = REPO / "translator" / "bench_stc.py"
    if not script.is_file():
        line(name, "skipped: translator/bench_stc.py not present", "SKIPPED")
        return
    try:
        out = run([PY, script, "--repeat", 1 if quick else 3])
    except (BenchError, subprocess.SubprocessError, OSError) as e:
        error(name, str(e))
        return
    # bench_stc.py prints one line per case; this figure is its "N lines/s" line
    speed = next((ln.strip() for ln in out.splitlines() if "lines/s" in ln), "")
    m = re.search(r"([\d,]+) lines/s", speed)
    if not m:
        line(name, f"skipped: no 'N lines/s' in the output of translator/bench_stc.py "
             f"({out.strip()[:80]!r})", "SKIPPED")
        return
    r = float(m.group(1).replace(",", ""))
    line(name, f"{r:.0f} lines/s (translator/bench_stc.py: {speed}; "
         f"{r / 5000:.2f} of target >= 5000 lines/s)", "OK" if r >= 5000 else "MISSED")
