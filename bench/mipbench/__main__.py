"""The benchmarks of issue 8: prints the machine and one line per figure with its ratio to the
target. `make bench` runs it; BENCH_QUICK=1 (or --quick) runs every figure with small counts.

    python -m mipbench [--quick] [--only NAME[,NAME...]]

Figure lines look like `name: <value> (<details>; target ...) OK|MISSED|SKIPPED|PENDING|ERROR`.
A figure that cannot be measured prints an ERROR line with the reason and the run exits 1 at
the end (after every other figure); a missed target is not an error. docs/benchmarks.md has
the latest full-run figures, the models and how to reproduce them."""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from .common import BUILD, ERRORS, machine
from .goodput import fig_goodput, fig_goodput_pipelined
from .rtu import fig_fc23_gain, fig_goodput_rtu
from .scan_cost import fig_scan_cost
from .emulator import fig_emulator_throughput
from .cosim_speed import fig_cosim_scale, fig_cosim_speed
from .translator import fig_translator, fig_translator_inprocess
from .memory import fig_memory
from .readout import fig_chain, fig_kit_scenario, fig_readout

# ---------------------------------------------------------------- main

FIGURES = ["goodput", "goodput_pipelined", "goodput_rtu", "fc23_gain", "scan_cost", "emu_throughput",
           "cosim_speed", "cosim_scale", "translator", "memory", "readout", "kit_scenario", "chain"]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m mipbench",
                                 description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--quick", action="store_true", default=os.environ.get("BENCH_QUICK") == "1")
    ap.add_argument("--only", default=",".join(FIGURES))
    a = ap.parse_args(argv)
    only = [x.strip() for x in a.only.split(",") if x.strip()]
    bad = [x for x in only if x not in FIGURES]
    if bad:
        print(f"mipbench: error: unknown figure {bad[0]!r} (one of {', '.join(FIGURES)})",
              file=sys.stderr)
        return 2
    if os.environ.get("BENCH_MATIEC") not in (None, "", "off"):
        print("mipbench: error: BENCH_MATIEC must be 'off' or unset", file=sys.stderr)
        return 2
    BUILD.mkdir(parents=True, exist_ok=True)
    print(f"bench: {'quick' if a.quick else 'full'} run, {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}",
          flush=True)
    machine()
    t0 = time.perf_counter()
    took = []
    with tempfile.TemporaryDirectory(dir=BUILD, prefix="work-") as work:
        work = Path(work)
        steps = {
            "goodput": lambda: fig_goodput(a.quick, work / "goodput"),
            "goodput_pipelined": lambda: fig_goodput_pipelined(a.quick, work / "pipelined"),
            "goodput_rtu": lambda: fig_goodput_rtu(a.quick, work / "rtu"),
            "fc23_gain": lambda: fig_fc23_gain(a.quick, work / "fc23"),
            "scan_cost": lambda: fig_scan_cost(a.quick),
            "emu_throughput": lambda: fig_emulator_throughput(a.quick),
            "cosim_speed": lambda: fig_cosim_speed(a.quick, work / "speed"),
            "cosim_scale": lambda: fig_cosim_scale(a.quick, work / "scale"),
            "translator": lambda: (fig_translator(a.quick), fig_translator_inprocess(a.quick)),
            "memory": lambda: fig_memory(a.quick),
            "readout": lambda: fig_readout(a.quick, work / "readout"),
            "kit_scenario": lambda: fig_kit_scenario(a.quick, work / "kit"),
            "chain": lambda: fig_chain(a.quick, work / "chain"),
        }
        for fig in FIGURES:
            if fig in only:
                t = time.perf_counter()
                steps[fig]()
                took.append(f"{fig} {time.perf_counter() - t:.1f}")
    print(f"bench: done in {time.perf_counter() - t0:.1f} s (builds included: {', '.join(took)})"
          + (f"; not measured: {', '.join(ERRORS)}" if ERRORS else ""), flush=True)
    return 1 if ERRORS else 0


def entry():
    """The console script and `python -m mipbench`: main() with Ctrl-C and a cut pipe said quietly."""
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        sys.exit(130)
    except BrokenPipeError:          # output cut short (| head): stop quietly, servers are gone
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(141)


if __name__ == "__main__":
    entry()
