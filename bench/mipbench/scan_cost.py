"""Figure 2: the blocks' cost per scan, stc against matiec (callgrind instructions)."""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from .common import BUILD, BenchError, PAIR_ST, PY, ST_LIB, error, line, matiec_env, run

# ---------------------------------------------------------------- 2. scan cost

def build_pair(compiler, env=None):
    out = BUILD / f"pair-{compiler}"
    code = ("import sys\nfrom plcharness.build import build_program, BuildError\n"
            "try:\n"
            "    r = build_program(sys.argv[3:], sys.argv[2], compiler=sys.argv[1])\n"
            "except BuildError as e:\n"
            "    sys.exit(str(e).splitlines()[0] if str(e) else 'build failed')\n"
            "print(r.executable)\n")
    return Path(run([PY, "-c", code, compiler, out, *ST_LIB, PAIR_ST], env=env).strip())


FB_BODIES = ("MIP_SENDER_body__", "MIP_RECEIVER_body__")   # the same names from stc and matiec


def inclusive_cost(callgrind_out: str, fns) -> int:
    """Instructions executed inside fns, callees included, from a callgrind output file: the
    inclusive costs of the calls into them (or into gcc's clones of them, fn.part.0,
    fn.constprop.1 ...) from outside them. gcc splits matiec's FB bodies (partial inlining of
    the EN test): the callers then call MIP_SENDER_body__.part.0 and never the function of
    that name, so a count by name alone (callgrind's --toggle-collect) gives 0 for matiec."""
    def ours(name):
        return any(name == f or name.startswith(f + ".") for f in fns)
    npos, total, fn, cfn, edge = 1, 0, None, None, False
    for l in callgrind_out.splitlines():
        if edge:                                  # the line after calls=: positions, costs
            edge = False
            if ours(cfn) and not ours(fn or ""):
                total += int(l.split()[npos])
        elif l.startswith("positions:"):
            npos = len(l.split()) - 1
        elif l.startswith("fn="):
            fn = l[3:].strip()
        elif l.startswith("cfn="):
            cfn = l[4:].strip()
        elif l.startswith("calls="):
            edge = True
    return total


def callgrind_total(exe, scans, fns=("config_run__",)):
    """Instructions executed inside fns (config_run__: the generated code and what it calls)
    over `scans` virtual scans of the plc executable; deterministic."""
    with tempfile.TemporaryDirectory(dir=BUILD) as d:
        outf = Path(d) / "callgrind.out"
        run(["valgrind", "--tool=callgrind", "--compress-strings=no", "--compress-pos=no",
             f"--callgrind-out-file={outf}", exe, "-m", "virtual", "-n", scans])
        total = inclusive_cost(outf.read_text(), fns)
        if not total:
            raise BenchError(f"callgrind counted no instructions in {', '.join(fns)}")
        return total


WARM = 100      # scans before the measured window: start-up, the sender's quiet wait (200 ms)


def per_scan(exe, scans, fns=("config_run__",)):
    """Steady-state instructions per scan: (cost of WARM + scans) - (cost of WARM), / scans."""
    return (callgrind_total(exe, WARM + scans, fns) - callgrind_total(exe, WARM, fns)) / scans


PAIR_RECORDS = """\
import sys
from plcharness import Plc
compiler, warm, scans, workdir, *sources = sys.argv[1:]
plc = Plc.build(sources, workdir=workdir, compiler=compiler)
plc.scan(int(warm))
a = plc["BENCHPAIR.udiRecords"]
plc.scan(int(scans))
print(plc["BENCHPAIR.udiRecords"] - a)
"""


def pair_records(compiler, scans, env=None):
    """Records the receiver delivered in the measured window, through plcharness."""
    with tempfile.TemporaryDirectory(dir=BUILD) as d:
        return int(run([PY, "-c", PAIR_RECORDS, compiler, WARM, scans, d, *ST_LIB, PAIR_ST],
                       env=env).strip())


SCAN_COST_TARGET = 0.5   # stc's instructions per scan, as a share of matiec's (issue 39)


def fig_scan_cost(quick):
    scans = 300 if quick else 3000
    name = "scan_cost"
    if not shutil.which("valgrind"):
        error(name, "valgrind not installed (Debian package valgrind)")
        return None
    try:
        exe = build_pair("stc")
        stc = per_scan(exe, scans)
        stc_fb = per_scan(exe, scans, FB_BODIES)
        rec_stc = pair_records("stc", scans)
        if rec_stc == 0:
            raise BenchError("bench_pair.st delivered no record in the measured window")
    except (BenchError, subprocess.SubprocessError, OSError, ValueError) as e:
        error(name, str(e))
        return None
    env = matiec_env()
    what = (f"instructions per scan in config_run__, callgrind, scans {WARM}..{WARM + scans} "
            f"of bench/st/bench_pair.st (1 MIP_Sender + 1 MIP_Receiver back to back, "
            f"{rec_stc} records in the window), -O2")
    if env is None:
        why = ("BENCH_MATIEC=off" if os.environ.get("BENCH_MATIEC") == "off" else
               "iec2c not on PATH and not in /opt/src/matiec (matiec is not installed here)")
        line(name, f"stc {stc:.0f} {what}, of which {stc_fb:.0f} in the two FB bodies; matiec "
             f"figure skipped: {why}; target stc <= {SCAN_COST_TARGET:.2f} x matiec",
             "SKIPPED")
        return None
    try:
        exe = build_pair("matiec", env)
        mat = per_scan(exe, scans)
        mat_fb = per_scan(exe, scans, FB_BODIES)
        rec_mat = pair_records("matiec", scans, env)
    except (BenchError, subprocess.SubprocessError, OSError, ValueError) as e:
        error(name, f"stc {stc:.0f}; matiec build or run failed: {e}")
        return None
    if rec_mat != rec_stc:
        error(name, f"stc and matiec builds behave differently ({rec_stc} vs {rec_mat} records "
              "in the window): the comparison would be meaningless")
        return None
    r = stc / mat
    line(name, f"{r:.3f} of matiec (stc {stc:.0f}, matiec {mat:.0f} {what}; in the two FB "
         f"bodies alone stc {stc_fb:.0f}, matiec {mat_fb:.0f}: {stc_fb / mat_fb:.3f}; "
         f"target <= {SCAN_COST_TARGET:.2f})",
         "OK" if r <= SCAN_COST_TARGET else "MISSED")
