"""Helpers for the translator tests: run stc, build the generated C with a test main, run scans."""
import contextlib
import io
import os
import re
import shutil
import subprocess
import sys

from mipprograms.common import config

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
HERE = os.path.dirname(os.path.abspath(__file__))
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O0"]


def stc_cmd():
    exe = os.path.join(ROOT, ".venv", "bin", "stc")
    if os.path.exists(exe):
        return [exe]
    return [sys.executable, "-m", "stc.cli"]


def run_stc(args, cwd=None):
    """The stc executable, as a user runs it (exit status, usage errors, output)."""
    return subprocess.run(stc_cmd() + list(args), capture_output=True, text=True, cwd=cwd)


def translate(args):
    """stc's command line in this process (stc.cli.main, the executable's own code) with its
    exit status and printed output: the corpora run it hundreds of times, and a new Python
    with lark for each took 0.3 s of the 0.4. The executable itself is tested through run_stc."""
    from stc import cli
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = cli.main(list(args))
        except SystemExit as e:   # argparse's usage errors
            rc = e.code if isinstance(e.code, int) else 2
    return subprocess.CompletedProcess(["stc"] + list(args), rc, out.getvalue(), err.getvalue())


def symtab_c(outdir):
    """C table {path, type, address} generated from SYMBOLS.tsv (the harness's view)."""
    decls, rows = [], []
    with open(os.path.join(outdir, "SYMBOLS.tsv")) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("#decl\t"):
                decls.append(line.split("\t", 1)[1])
            elif line.startswith("#") or line.startswith("path\t") or not line:
                continue
            else:
                path, typ, kind, ref = line.split("\t")
                rows.append((path, typ, ref))
    out = ['#include "POUS.h"'] + decls
    out.append("struct stc_sym { const char *path; const char *type; void *addr; };")
    # filled at run time: located c_refs go through pointers the runtime sets
    out.append(f"struct stc_sym stc_symtab[{len(rows) + 1}];")
    out.append(f"const int stc_symtab_len = {len(rows)};")
    out.append("void stc_symtab_init(void)")
    out.append("{")
    for i, (path, typ, ref) in enumerate(rows):
        out.append(f'    stc_symtab[{i}].path = "{path}"; stc_symtab[{i}].type = "{typ}"; '
                   f'stc_symtab[{i}].addr = (void *)&({ref});')
    out.append("}")
    return "\n".join(out) + "\n"


def build(st_files, workdir, cc=None, semantics=None):
    """Translate and compile; returns path of the executable. Raises AssertionError with the
    compiler output on failure. semantics: None (stc's default) or "matiec" / "iec"."""
    outdir = os.path.join(workdir, "gen")
    sem = [f"--semantics={semantics}"] if semantics else []
    r = translate(sem + ["-o", outdir] + list(st_files))
    assert r.returncode == 0, f"stc failed ({r.returncode}):\n{r.stderr}"
    with open(os.path.join(outdir, "stc_symtab.c"), "w") as f:
        f.write(symtab_c(outdir))
    with open(os.path.join(outdir, "SOURCES.txt")) as f:
        srcs = [os.path.join(outdir, x.strip()) for x in f if x.strip()]
    exe = os.path.join(workdir, "prog")
    cmd = [cc or os.environ.get("CC", "cc")] + CFLAGS + ["-I", outdir, "-o", exe] + srcs + [
        os.path.join(outdir, "stc_symtab.c"), os.path.join(HERE, "stc_test_main.c"), "-lm"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    assert p.returncode == 0, f"C compile failed:\n{' '.join(cmd)}\n{p.stderr}"
    return exe


def run(exe, scans, sets=()):
    p = subprocess.run([exe, str(scans)] + [f"{k}={v}" for k, v in sets],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, f"program failed ({p.returncode}): {p.stderr}"
    values = {}
    for line in p.stdout.splitlines():
        k, _, v = line.partition("=")
        values[k] = v
    return values


def lookup(values, path):
    """Value by full path or by a unique suffix (e.g. 'MAIN0.X'), case-insensitive."""
    path = path.upper()
    if path in values:
        return values[path]
    hits = [k for k in values if k.endswith("." + path)]
    assert len(hits) == 1, f"{path}: {'ambiguous' if hits else 'no such symbol'} ({hits[:5]})"
    return values[hits[0]]


_SCANS = re.compile(r"\(\*\s*SCANS\s+(\d+)\s*\*\)", re.I)
_EXPECT = re.compile(r"\(\*\s*EXPECT\s+(\S+)\s*=\s*(.*?)\s*\*\)", re.I)
_SET = re.compile(r"\(\*\s*SET\s+(\S+)\s*=\s*(\S+)\s*\*\)", re.I)
_ERROR = re.compile(r"\(\*\s*ERROR\s+(\d+):(\d+):\s*(.*?)\s*\*\)", re.I)


_EXPECT_MODE = re.compile(r"\(\*\s*EXPECT-(MATIEC|OPENPLC|IEC)\s+(\S+)\s*=\s*(.*?)\s*\*\)", re.I)


def expectations(text, semantics="matiec"):
    """(scans, [(path, value)], [(path, value)]) for one semantics: (* EXPECT p = v *) holds
    in every mode, (* EXPECT-MATIEC p = v *) in both matiec flavours (upstream and OpenPLC's
    fork) unless (* EXPECT-OPENPLC p = v *) names the same path, (* EXPECT-IEC p = v *) in
    the IEC mode only."""
    m = _SCANS.search(text)
    scans = int(m.group(1)) if m else 1
    expects = _EXPECT.findall(text)
    modes = [(mode.lower(), p, v) for mode, p, v in _EXPECT_MODE.findall(text)]
    if semantics == "openplc":
        fork = [(p, v) for mode, p, v in modes if mode == "openplc"]
        own = {p.upper() for p, _ in fork}
        expects += [(p, v) for mode, p, v in modes if mode == "matiec" and p.upper() not in own]
        expects += fork
    else:
        expects += [(p, v) for mode, p, v in modes if mode == semantics]
    return scans, expects, _SET.findall(text)


def expected_errors(text):
    return [(int(a), int(b), msg) for a, b, msg in _ERROR.findall(text)]


_FLAVOUR_PROBE = """PROGRAM Main
VAR f : F_TRIG; q : BOOL; END_VAR
f(CLK := FALSE);
q := f.Q;
END_PROGRAM
""" + config("Main", "Main0", task="t")
_FLAVOUR_MAIN = """#include <stdio.h>
#include "iec_std_lib.h"
#include "POUS.h"
TIME __CURRENT_TIME;
BOOL __DEBUG;
extern MAIN RES0__MAIN0;
void config_init__(void);
void config_run__(unsigned long tick);
int main(void) { config_init__(); config_run__(0); printf("%d\\n", (int)RES0__MAIN0.Q.value); return 0; }
"""
_flavour = {}


def iec2c_flavour(exe, lib, workdir):
    """Which matiec the iec2c at exe is: "matiec" (upstream) or "openplc" (the fork OpenPLC v3
    ships). IEC2C_FLAVOUR names it; otherwise a probe tells them apart by their F_TRIG (on
    its first call with CLK FALSE, upstream's gives Q, the fork's does not)."""
    if os.environ.get("IEC2C_FLAVOUR"):
        return os.environ["IEC2C_FLAVOUR"]
    if exe in _flavour:
        return _flavour[exe]
    d = os.path.join(str(workdir), "flavour")
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "probe.st"), "w") as f:
        f.write(_FLAVOUR_PROBE)
    with open(os.path.join(d, "main.c"), "w") as f:
        f.write(_FLAVOUR_MAIN)
    subprocess.run([exe, "-I", lib, "-T", d, os.path.join(d, "probe.st")], check=True,
                   capture_output=True)
    srcs = [os.path.join(d, f) for f in ("main.c", "Config0.c", "Res0.c")]
    subprocess.run(["cc", "-w", "-I", d, "-I", os.path.join(lib, "C"), "-o",
                    os.path.join(d, "probe"), *srcs, "-lm"], check=True, capture_output=True)
    out = subprocess.run([os.path.join(d, "probe")], check=True, capture_output=True, text=True)
    _flavour[exe] = "matiec" if out.stdout.strip() == "1" else "openplc"
    return _flavour[exe]


def find_iec2c():
    exe = os.environ.get("IEC2C") or shutil.which("iec2c")
    lib = os.environ.get("MATIEC_LIB")
    if exe and not lib:
        cand = os.path.join(os.path.dirname(os.path.realpath(exe)), "lib")
        lib = cand if os.path.isdir(cand) else None
    return exe, lib


def check_accept(path, workdir, semantics=None):
    """A corpus program translates, runs its (* SCANS n *) and gives its (* EXPECT *) values."""
    with open(path) as f:
        text = f.read()
    scans, expects, sets = expectations(text, semantics or "matiec")
    assert expects, f"{path}: no (* EXPECT ... *) lines"
    exe = build([path], str(workdir), semantics=semantics)
    values = run(exe, scans, sets)
    for sym, want in expects:
        got = lookup(values, sym)
        assert got == want.replace(" ", ""), f"{sym}: got {got}, want {want}"


def check_reject(path, workdir):
    """A corpus program fails with exactly located (* ERROR line:col: message *) errors."""
    with open(path) as f:
        want = expected_errors(f.read())
    assert want, f"{path}: no (* ERROR line:col: message *) lines"
    r = translate(["-o", os.path.join(str(workdir), "out"), path])
    assert r.returncode == 1, f"accepted (rc={r.returncode}): {r.stderr}"
    assert "Traceback" not in r.stderr and "internal" not in r.stderr, r.stderr
    lines = r.stderr.splitlines()
    for line, col, msg in want:
        prefix = f"{path}:{line}:{col}: error: "
        hits = [x for x in lines if x.startswith(prefix)]
        assert hits, f"no error at {line}:{col}; got:\n{r.stderr}"
        assert any(msg.lower() in x.lower() for x in hits), \
            f"error at {line}:{col} does not mention {msg!r}:\n{r.stderr}"
