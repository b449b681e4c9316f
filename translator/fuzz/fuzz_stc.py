#!/usr/bin/env python3
"""Mutation fuzzer for the stc front end and code generator.

Takes the ST corpus (tests/translator/accept, tests/translator/reject, st_lib, plc), mutates
files at byte and token level, and runs the translator in-process on each mutant. A finding is
  - any exception escaping the translator (it must report errors, never crash), or
  - a mutant that stc accepts but whose C does not compile with -std=c99 -Wall -Wextra -Werror, or
  - a mutant taking longer than --case-timeout seconds.
Findings are written to --findings (default build/translator/fuzz-findings) with the reason.

  python translator/fuzz/fuzz_stc.py --seconds 600          # long run
  python translator/fuzz/fuzz_stc.py --cases 300 --seed 1   # short deterministic run
"""
import argparse
import glob
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))

from stc.compiler import compile_files   # stc: installed by make venv (translator/pyproject.toml)
from stc.cgen import Gen
from stc.diag import Diagnostics

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-c"]
TOKEN_RE = re.compile(r"\(\*.*?\*\)|[A-Za-z_][A-Za-z0-9_]*#[A-Za-z0-9_#.+-]*|[A-Za-z_][A-Za-z0-9_]*"
                      r"|%[A-Za-z0-9.*]+|[0-9][0-9_.#A-Fa-f]*|:=|=>|<=|>=|<>|\.\.|\*\*|\S|\s+", re.S)
EXTRA_TOKENS = ["IF", "THEN", "END_IF", ";", ":=", "(", ")", "[", "]", "CASE", "OF", "END_CASE",
                "FOR", "TO", "BY", "DO", "END_FOR", "WHILE", "END_WHILE", "REPEAT", "UNTIL",
                "END_REPEAT", "EXIT", "CONTINUE", "RETURN", "VAR", "END_VAR", "VAR_INPUT",
                "VAR_IN_OUT", "VAR_OUTPUT", "VAR_EXTERNAL", "VAR_GLOBAL", "CONSTANT", "AT",
                "%IW3", "%QX1.7", "%MD9", "ARRAY", "[0..3]", "OF", "STRUCT", "END_STRUCT", "TYPE",
                "END_TYPE", "TON", "R_TRIG", "CTUD", "T#5ms", "T#-1s", "16#FFFF", "-32768",
                "2147483647", "4294967295", "18446744073709551615", "-9223372036854775808",
                "0", "1", "WORD#16#1", "INT#-1", "TRUE", "NOT", "AND", "OR", "XOR", "MOD", "/",
                "*", "+", "-", "=", "<>", "SHL(", "ROR(", "MIN(", "MUX(", "LIMIT(", "SEL(",
                "ABS(", "INT_TO_UINT(", "TIME_TO_DINT(", "DINT_TO_TIME(", "REAL_TO_INT(",
                "LREAL", "REAL", "1.5", "1.0E38", "LINT", "ULINT", "LWORD", "SINT", "USINT",
                "BYTE", "DWORD", "UDINT", "TIME", "BOOL", ".", ",", ":", "=>", "E#X", "x", "i"]


def corpus_files():
    pats = ["tests/translator/accept/*.st", "tests/translator/reject/*.st", "st_lib/*/*.st", "plc/*.st",
            "plc/**/*.st"]
    files = []
    for p in pats:
        files += glob.glob(os.path.join(ROOT, p), recursive=True)
    return sorted(set(files))


NUMBERS = ["0", "1", "2", "7", "-1", "127", "128", "255", "256", "-128", "32767", "-32768", "65535",
           "2147483647", "-2147483648", "4294967295", "16#FF", "2#1010", "1_000"]
TYPES = ["BOOL", "BYTE", "WORD", "DWORD", "LWORD", "SINT", "INT", "DINT", "LINT", "USINT", "UINT",
         "UDINT", "ULINT", "REAL", "LREAL", "TIME"]
OPS = ["+", "-", "*", "/", "MOD", "AND", "OR", "XOR", "=", "<>", "<", ">", "<=", ">="]


def mutate_mild(rng, text):
    """Small, often type-correct changes so that many mutants reach the code generator."""
    toks = TOKEN_RE.findall(text)
    idx = [i for i, t in enumerate(toks) if not t.isspace() and not t.startswith("(*")]
    if not idx:
        return text
    for _ in range(1 if rng.random() < 0.7 else 2):
        i = rng.choice(idx)
        t = toks[i]
        if t[0].isdigit():
            toks[i] = rng.choice(NUMBERS)
        elif t.upper() in TYPES:
            toks[i] = rng.choice(TYPES)
        elif t.upper() in OPS:
            toks[i] = rng.choice(OPS)
        elif t[0].isalpha() or t[0] == "_":
            names = [toks[j] for j in idx if toks[j][0].isalpha() and toks[j].upper() not in TYPES]
            toks[i] = rng.choice(names)
        else:
            toks[i] = rng.choice(OPS + [";", ",", ":="])
    return "".join(toks)


def mutate(rng, text, donors):
    if rng.random() < 0.5:
        return mutate_mild(rng, text)
    ops = rng.randint(1, 3)
    for _ in range(ops):
        kind = rng.random()
        if kind < 0.3 and text:
            b = bytearray(text.encode("utf-8", "replace"))
            for _ in range(rng.randint(1, 3)):
                if not b:
                    break
                i = rng.randrange(len(b))
                r = rng.random()
                if r < 0.4:
                    b[i] = rng.randrange(256)
                elif r < 0.7:
                    del b[i:i + rng.randint(1, 8)]
                else:
                    b[i:i] = bytes([rng.choice(b"();:=.,[]#%*{}'/0123456789_-+")])
            text = b.decode("utf-8", "replace")
        else:
            toks = TOKEN_RE.findall(text)
            words = [i for i, t in enumerate(toks) if not t.isspace()]
            if not words:
                toks = [rng.choice(EXTRA_TOKENS)]
                words = [0]
            i = rng.choice(words)
            r = rng.random()
            if r < 0.25:
                del toks[i]
            elif r < 0.45:
                toks.insert(i, rng.choice(EXTRA_TOKENS) + " ")
            elif r < 0.6:
                j = rng.choice(words)
                toks[i], toks[j] = toks[j], toks[i]
            elif r < 0.75:
                toks[i] = rng.choice(EXTRA_TOKENS)
            elif r < 0.9:
                d = rng.choice(donors)
                dt = [t for t in TOKEN_RE.findall(d) if not t.isspace()]
                if dt:
                    k = rng.randrange(len(dt))
                    toks[i:i] = [" " + " ".join(dt[k:k + rng.randint(1, 12)]) + " "]
            else:
                j = rng.choice(words)
                a, c = sorted((i, j))
                toks[c:c] = toks[a:c + 1]
            text = "".join(toks)
    return text


class Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise Timeout()


def run_case(name, text, workdir, cc, case_timeout, semantics="matiec"):
    """Returns None if fine, else a one-line reason."""
    diags = Diagnostics()
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(case_timeout)
    try:
        project = compile_files([(name, text, False)], diags, semantics)
        if diags:
            lines = diags.format()
            for ln in lines:
                if not re.match(r"^.*?:\d+:\d+: error: |^.*?: error: ", ln):
                    return f"badly formatted diagnostic: {ln!r}"
            return None
        out = os.path.join(workdir, "gen")
        shutil.rmtree(out, ignore_errors=True)
        Gen(project, [name]).generate(out)
    except Timeout:
        return f"timeout (> {case_timeout} s)"
    except RecursionError:
        return "exception: RecursionError\n" + traceback.format_exc()
    except Exception:
        return "exception: " + traceback.format_exc()
    finally:
        signal.alarm(0)
    with open(os.path.join(out, "SOURCES.txt")) as f:
        srcs = [os.path.join(out, x.strip()) for x in f if x.strip()]
    for src in srcs:
        p = subprocess.run([cc] + CFLAGS + ["-I", out, "-o", os.devnull, src],
                           capture_output=True, text=True)
        if p.returncode != 0:
            return "C does not compile: " + p.stderr[:2000]
    return "ACCEPTED"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=None, help="run for this long")
    ap.add_argument("--cases", type=int, default=None, help="run this many mutants")
    ap.add_argument("--seed", type=int, default=None, help="random seed (default: time)")
    ap.add_argument("--findings", default=os.path.join(ROOT, "build", "translator", "fuzz-findings"))
    ap.add_argument("--case-timeout", type=int, default=20)
    ap.add_argument("--cc", default=os.environ.get("CC", "cc"))
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if args.seconds is None and args.cases is None:
        args.seconds = 60
    seed = args.seed if args.seed is not None else int(time.time())
    rng = random.Random(seed)
    files = corpus_files()
    texts = []
    for f in files:
        with open(f, encoding="utf-8", errors="replace") as fh:
            texts.append((os.path.relpath(f, ROOT), fh.read()))
    if not texts:
        print("fuzz_stc: no corpus files found", file=sys.stderr)
        return 2
    donors = [t for _, t in texts]
    accept = [(n, t) for n, t in texts if "/accept/" in n or n.startswith(("st_lib", "plc"))]
    sys.setrecursionlimit(10000)
    start = time.time()
    n = accepted = 0
    findings = []
    with tempfile.TemporaryDirectory(prefix="stc-fuzz-") as work:
        while True:
            if args.cases is not None and n >= args.cases:
                break
            if args.seconds is not None and time.time() - start >= args.seconds:
                break
            pool = accept if accept and rng.random() < 0.6 else texts
            name, text = rng.choice(pool)
            mutant = mutate(rng, text, donors)
            n += 1
            # both semantics: the C of each must compile
            res = run_case(name, mutant, work, args.cc, args.case_timeout,
                           "iec" if n % 2 else "matiec")
            if res == "ACCEPTED":
                accepted += 1
            elif res is not None:
                os.makedirs(args.findings, exist_ok=True)
                base = os.path.join(args.findings, f"finding-{seed}-{n}")
                with open(base + ".st", "w") as fh:
                    fh.write(mutant)
                with open(base + ".txt", "w") as fh:
                    fh.write(f"from {name}, seed {seed}, case {n}\n{res}\n")
                findings.append(base)
                if not args.quiet:
                    print(f"FINDING {base}.st: {res.splitlines()[0] if res else ''}", flush=True)
    dt = time.time() - start
    print(f"fuzz_stc: seed {seed}, {n} cases in {dt:.1f} s ({n / dt if dt else 0:.1f}/s), "
          f"{accepted} accepted and compiled, {len(findings)} findings")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
