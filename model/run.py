#!/usr/bin/env python3
"""Runs the spin model of the MIP logger transfer in every configuration and prints, per
configuration, states stored, depth reached, time and the verdict.

Each configuration either must hold every property ("holds") or is a documented weakness of
peers that follow only the Piciorgros note ("known: KIND"): the run then must find exactly
that kind of violation, so the model keeps showing why our extensions exist. Any other
outcome ends the runner non-zero. A violation prints its counterexample as a short trace.

Each configuration is checked with the cheapest search that proves what it must show:
a configuration that must hold, or must show a hang ("known: progress"), by pan's
acceptance-cycle search under weak fairness (`pan -a -f`: the progress property, with every
assertion checked on the way in every reachable state: env.pml's claim goes on after the
sender finished); one that must show a safety violation by a breadth-first
safety search (`-DSAFETY -DBFS`), which stops at the shortest counterexample and gives its
trace in the same run. A search that ends without covering the whole state space (memory,
depth or time) proves nothing: its verdict is INCOMPLETE and fails the run.

usage: model/run.py [-k SUBSTRING] [--quick] [--tier all|check|large] [--list] [--junit FILE] [--trace-dir DIR] [--work DIR]
"""
import argparse
import concurrent.futures
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from xml.sax.saxutils import escape

# run as a script (python3 model/run.py): Python puts this folder first on sys.path
from configs import CONFIGS, QUICK, bounded, large
from spin_search import run_one, search_for


def cost_rank(name):
    """Longest first, so that two workers end together: the bidirectional warm-restart and
    the pipelined must-fail configurations take minutes, most others seconds."""
    return (("bidi" in name and (name.startswith("warm") or "win2" in name)) * 4 + ("bidi" in name) * 2
            + name.startswith("warm") + ("rst" in name))


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-k", default="", help="run only configurations whose name contains this")
    ap.add_argument("-x", action="append", default=[], metavar="SUBSTRING",
                    help="leave out configurations whose name contains this (repeatable)")
    ap.add_argument("--exact", action="store_true", help="-k names one configuration exactly")
    ap.add_argument("--list", action="store_true", help="list the configurations and exit")
    ap.add_argument("--junit", help="write a JUnit XML report here")
    ap.add_argument("--trace-dir", help="write each counterexample trace to DIR/<name>.txt")
    ap.add_argument("--work", help="build directory (default: a temporary one)")
    ap.add_argument("--max-depth", type=int, default=200000)
    ap.add_argument("-D", action="append", default=[], metavar="NAME=VALUE",
                    help="an extra model define for every configuration (exploring variants)")
    ap.add_argument("-j", type=int, default=os.cpu_count() or 2,
                    help="configurations checked in parallel (default: one per core)")
    ap.add_argument("--quick", action="store_true",
                    help="only the quick set: one configuration of each family (make test; "
                         "whatever --tier says)")
    ap.add_argument("--tier", choices=("all", "check", "large"), default="all",
                    help="all: every configuration (default); check: all but the large ones "
                         "(make check); large: only those (make check-large; model/configs.py LARGE)")
    ap.add_argument("--timeout", type=int, default=1200,
                    help="seconds one search may take before it counts as INCOMPLETE (default 1200)")
    ap.add_argument("--memlim", type=int, default=int(os.environ.get("MODEL_MEMLIM", "4096")),
                    help="MB one search may use before it counts as INCOMPLETE (default 4096, "
                         "or MODEL_MEMLIM)")
    ap.add_argument("--bounded-memlim", type=int, default=None, metavar="MB",
                    help="memory cap of the bounded configurations (model/configs.py BOUNDED; "
                         "default: their own cap; 0: no cap, as far as --memlim: make model-deep)")
    ap.add_argument("--collapse", action="store_true",
                    help="compile pan with -DCOLLAPSE: about 0.7 of the memory per state, about "
                         "1.5 times the search time (for variants larger than --memlim holds)")
    ap.add_argument("--pan-cache", help="keep compiled pan binaries here and reuse them "
                                        "(default: WORK/pan-cache when --work is given)")
    a = ap.parse_args(argv)
    if shutil.which("spin") is None:
        print("model/run.py: error: spin is not installed (Debian package 'spin')", file=sys.stderr)
        return 2
    extra = dict(d.split("=", 1) if "=" in d else (d, "1") for d in a.D)
    sel = [(n, dict(d, **extra), e, w) for n, d, e, w in CONFIGS
           if (n == a.k if a.exact else a.k in n) and (not a.quick or n in QUICK)
           and not any(x in n for x in a.x)
           and (a.quick or a.tier == "all" or (a.tier == "large") == large(n))]
    if a.list:
        for name, defs, expect, what in sel:
            search = search_for(expect, name) + (" bounded" if expect == "holds" and bounded(name) else "")
            print("%-36s %-24s %-16s %s" % (name, expect, search, what))
        return 0
    if not sel:
        print("model/run.py: error: no configuration matches -k %r" % a.k, file=sys.stderr)
        return 2
    work_root = a.work or tempfile.mkdtemp(prefix="mip-model-")
    os.makedirs(work_root, exist_ok=True)
    cache = a.pan_cache or (os.path.join(work_root, "pan-cache") if a.work else None)
    results = {}
    t_start = time.time()
    print("%-36s %10s %7s %7s  %-9s %s" % ("configuration", "states", "depth", "secs", "search",
                                           "verdict"))
    def one(c):
        name, defs, expect, what = c
        try:
            return run_one(name, defs, expect, work_root, a.max_depth, a.memlim, a.timeout, cache,
                           a.collapse, a.bounded_memlim)
        except (RuntimeError, subprocess.TimeoutExpired) as e:
            return dict(name=name, stored=None, depth=None, secs=0.0, ok=False, search="-",
                        verdict="ERROR " + " | ".join(str(e).splitlines()[:2]), kind=None, trace=[], raw=str(e))

    order = sorted(sel, key=lambda c: -cost_rank(c[0]))   # longest first
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.j)) as pool:
        futs = [pool.submit(one, c) for c in order]
        for fut in concurrent.futures.as_completed(futs):
            r = fut.result()
            name = r["name"]
            results[name] = r
            print("%-36s %10s %7s %7.1f  %-9s %s" % (name, r["stored"], r["depth"], r["secs"],
                                                     r["search"], r["verdict"]), flush=True)
            if r["trace"] and (not r["ok"] or os.environ.get("MODEL_TRACES")):
                for ln in r["trace"]:
                    print("      " + ln)
            if r["trace"] and a.trace_dir:
                os.makedirs(a.trace_dir, exist_ok=True)
                with open(os.path.join(a.trace_dir, re.sub(r"[^A-Za-z0-9]+", "_", name) + ".txt"), "w") as f:
                    f.write("%s: %s\n" % (name, r["verdict"]))
                    f.write("\n".join(r["trace"]) + "\n")
    results = [results[c[0]] for c in sel]   # the report in the matrix's order
    npass = sum(r["ok"] for r in results)
    nbounded = sum(r["verdict"].startswith("bounded") for r in results)
    nfail = len(results) - npass
    if a.junit:
        os.makedirs(os.path.dirname(os.path.abspath(a.junit)), exist_ok=True)
        with open(a.junit, "w") as f:
            f.write('<?xml version="1.0" encoding="UTF-8"?>\n<testsuite name="model" tests="%d" failures="%d">\n'
                    % (len(results), nfail))
            for r in results:
                f.write('  <testcase classname="model" name="%s" time="%.1f">' % (escape(r["name"]), r["secs"]))
                if not r["ok"]:
                    f.write('<failure message="%s">%s</failure>' % (
                        escape(r["verdict"], {'"': "&quot;"}), escape("\n".join(r["trace"]))))
                f.write("</testcase>\n")
            f.write("</testsuite>\n")
    if not a.work:
        shutil.rmtree(work_root, ignore_errors=True)
    print("model: %d configurations in %.0f s wall with %d jobs (%.0f s of searching)"
          % (len(results), time.time() - t_start, a.j, sum(r["secs"] for r in results)))
    if nbounded:
        print("model: %d of the passed are bounded searches, not proofs (model/configs.py BOUNDED)"
              % nbounded)
    print("model: %d passed, %d failed" % (npass, nfail))
    return 0 if nfail == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
