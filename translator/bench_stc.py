#!/usr/bin/env python3
"""Benchmark: translate a generated ST file of about 5,000 lines and print lines per second.

  python translator/bench_stc.py [--lines 5000] [--repeat 3]

The file mixes what real programs contain: TYPEs, FUNCTION_BLOCKs with timers, CASE state
machines, FOR loops over arrays, conversions, and a CONFIGURATION. Timed: parse + check + C
generation (in-process, grammar already loaded, i.e. what every file after the first costs);
the one-off grammar load is printed separately."""
import argparse
import sys
import tempfile
import time

BLOCK = """
FUNCTION_BLOCK Worker{n}
VAR_INPUT xStart : BOOL; wIn : WORD; END_VAR
VAR_OUTPUT xDone : BOOL; uCount : UINT; END_VAR
VAR
  eState : E_State;
  tWait : TON;
  rEdge : R_TRIG;
  aBuf : T_Buf;
  i : INT;
  uSum : UINT;
END_VAR
rEdge(CLK := xStart);
CASE eState OF
  E_State#IDLE:
    IF rEdge.Q THEN
      eState := E_State#BUSY;
      uCount := uCount + 1;
    END_IF;
  E_State#BUSY:
    uSum := 0;
    FOR i := 0 TO 15 DO
      aBuf[i] := wIn AND 16#FF;
      uSum := uSum + WORD_TO_UINT(aBuf[i]);
    END_FOR;
    tWait(IN := TRUE, PT := T#100ms);
    IF tWait.Q THEN
      tWait(IN := FALSE);
      eState := E_State#DONE;
    END_IF;
  E_State#DONE:
    xDone := TRUE;
    eState := E_State#IDLE;
END_CASE;
END_FUNCTION_BLOCK
"""

HEAD = """TYPE
  E_State : (IDLE, BUSY, DONE);
  T_Buf : ARRAY[0..15] OF WORD;
END_TYPE
"""


def generate(lines):
    parts = [HEAD]
    n = 0
    total = HEAD.count("\n")
    per = BLOCK.count("\n")
    while total + per + 30 < lines:
        parts.append(BLOCK.format(n=n))
        total += per
        n += 1
    decl = "".join(f"  w{i} : Worker{i};\n" for i in range(n))
    calls = "".join(f"w{i}(xStart := x, wIn := w);\n" for i in range(n))
    parts.append(f"PROGRAM Main\nVAR\n  x : BOOL;\n  w : WORD;\n{decl}END_VAR\nx := NOT x;\n{calls}END_PROGRAM\n")
    parts.append("CONFIGURATION Config0\nRESOURCE Res0 ON PLC\nTASK t(INTERVAL := T#10ms, PRIORITY := 0);\n"
                 "PROGRAM Main0 WITH t : Main;\nEND_RESOURCE\nEND_CONFIGURATION\n")
    return "".join(parts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lines", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    t0 = time.perf_counter()
    from stc import parser
    from stc.cgen import Gen
    from stc.compiler import compile_files
    from stc.diag import Diagnostics
    parser._get_parser()
    t_load = time.perf_counter() - t0
    text = generate(args.lines)
    nlines = text.count("\n")
    best = None
    with tempfile.TemporaryDirectory() as out:
        for _ in range(args.repeat):
            t = time.perf_counter()
            d = Diagnostics()
            project = compile_files([("bench.st", text, False)], d)
            if d:
                print("\n".join(d.format()[:10]), file=sys.stderr)
                return 1
            t_front = time.perf_counter() - t
            Gen(project, ["bench.st"]).generate(out)
            dt = time.perf_counter() - t
            if best is None or dt < best[0]:
                best = (dt, t_front)
    dt, t_front = best
    print(f"stc benchmark: {nlines} lines, best of {args.repeat}: {dt:.3f} s "
          f"(parse+check {t_front:.3f} s, C generation {dt - t_front:.3f} s) "
          f"-> {nlines / dt:,.0f} lines/s; grammar load {t_load:.3f} s")
    # comment-heavy input: a 2 MB comment, and 20,000 unclosed '(*' (the error path); both
    # were quadratic in time or memory before the comment pass was made linear
    big = "(*" + "comment line of text\n" * 100000 + "*)\n" + text
    t = time.perf_counter()
    d = Diagnostics()
    compile_files([("bench_comment.st", big, False)], d)
    t_big = time.perf_counter() - t
    unclosed = "PROGRAM Main\n" + "(* " * 20000 + "\nEND_PROGRAM\n"
    t = time.perf_counter()
    d = Diagnostics()
    compile_files([("bench_unclosed.st", unclosed, False)], d)
    t_unc = time.perf_counter() - t
    print(f"stc comments: {len(big) / 1e6:.1f} MB file with a 2 MB comment {t_big:.3f} s; "
          f"20,000 unclosed '(*' {t_unc:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
