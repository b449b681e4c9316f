#!/usr/bin/env python3
"""Runs the test suites of `make test` / `make check` side by side and sums them up.

  suite.py start   --results DIR                   forget the suites of an earlier run
  suite.py run     --results DIR NAME -- CMD ...   run one suite: its output goes to DIR/NAME.log,
                                                   one line when it starts and one when it ends
                                                   (on failure also the end of its log)
  suite.py summary --results DIR --title T NAME... the table (suite, tests, passed, failed,
                                                   skipped, seconds, CPU seconds) on stdout and in
                                                   DIR/timing.txt; exit 1 if a suite failed or
                                                   did not report

A suite's counts come from its JUnit files, DIR/NAME.xml and DIR/NAME-*.xml.
"""
import argparse
import glob
import json
import os
import resource
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

TAIL = 60


def counts(results, name):
    tests = failed = skipped = 0
    files = [os.path.join(results, name + ".xml")] + sorted(glob.glob(os.path.join(results, name + "-*.xml")))
    for f in files:
        if not os.path.exists(f):
            continue
        try:
            root = ET.parse(f).getroot()
        except ET.ParseError:
            failed += 1
            continue
        suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
        for s in suites:
            tests += int(s.get("tests", 0))
            failed += int(s.get("failures", 0)) + int(s.get("errors", 0))
            skipped += int(s.get("skipped", 0))
    return tests, failed, skipped


def cmd_start(a):
    d = os.path.join(a.results, "suites")
    os.makedirs(d, exist_ok=True)
    for f in glob.glob(os.path.join(d, "*.json")):
        os.remove(f)
    with open(os.path.join(d, "start"), "w") as f:
        f.write("%f\n" % time.time())
    return 0


def cmd_run(a):
    os.makedirs(os.path.join(a.results, "suites"), exist_ok=True)
    log = os.path.join(a.results, a.name + ".log")
    for f in [os.path.join(a.results, a.name + ".xml")] + glob.glob(os.path.join(a.results, a.name + "-*.xml")):
        os.remove(f) if os.path.exists(f) else None   # no counts of an earlier run
    print("suite %-22s started" % a.name, flush=True)
    t0 = time.time()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(log, "w") as out:
        # close_fds=False: a make inside keeps the jobserver of the make that runs the suites
        rc = subprocess.call(a.command, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                             close_fds=False)
    secs = time.time() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # the CPU time of every process the suite ran and waited for: what it costs on a busy
    # machine, where the wall time depends on what runs beside it
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    tests, failed, skipped = counts(a.results, a.name)
    if rc != 0 and failed == 0:
        failed = 1   # it failed without a JUnit failure: a build or a crash
    with open(os.path.join(a.results, "suites", a.name + ".json"), "w") as f:
        json.dump(dict(name=a.name, rc=rc, secs=secs, cpu=cpu, tests=tests, failed=failed,
                       skipped=skipped), f)
    if rc == 0:
        print("suite %-22s ok      %6.0f s  %5d tests, %d skipped" % (a.name, secs, tests, skipped), flush=True)
    else:
        with open(log, errors="replace") as f:
            lines = f.read().splitlines()
        print("suite %-22s FAILED  %6.0f s  (exit %d; the end of %s:)" % (a.name, secs, rc, log))
        for ln in lines[-TAIL:]:
            print("  | " + ln)
        sys.stdout.flush()
    return rc


def cmd_summary(a):
    d = os.path.join(a.results, "suites")
    try:
        with open(os.path.join(d, "start")) as f:
            wall = time.time() - float(f.read())
    except (OSError, ValueError):
        wall = None
    rows, bad = [], []
    for name in a.names:
        try:
            with open(os.path.join(d, name + ".json")) as f:
                rows.append(json.load(f))
        except (OSError, ValueError):
            rows.append(dict(name=name, rc=None, secs=0.0, cpu=0.0, tests=0, failed=1, skipped=0))
    lines = ["%s: the suites" % a.title,
             "%-24s %7s %7s %7s %7s %8s %8s" % ("suite", "tests", "passed", "failed", "skipped", "seconds",
                                               "cpu s")]
    for r in rows:
        passed = r["tests"] - r["failed"] - r["skipped"]
        note = "" if r["rc"] == 0 else ("  (did not run)" if r["rc"] is None else "  (exit %d)" % r["rc"])
        if r["rc"] != 0:
            bad.append(r["name"])
        lines.append("%-24s %7d %7d %7d %7d %8.0f %8.0f%s" % (r["name"], r["tests"], max(passed, 0), r["failed"],
                                                           r["skipped"], r["secs"], r.get("cpu", 0.0), note))
    t = sum(r["tests"] for r in rows)
    fl = sum(r["failed"] for r in rows)
    sk = sum(r["skipped"] for r in rows)
    lines.append("%-24s %7d %7d %7d %7d %8s %8.0f" % ("all", t, t - fl - sk, fl, sk,
                                                     "%.0f" % wall if wall is not None else "?",
                                                     sum(r.get("cpu", 0.0) for r in rows)))
    lines.append("(seconds: each suite's own wall time; 'all': the wall time of the whole run, suites side "
                 "by side; cpu s: the CPU time of the suite's processes, which the cores share)")
    text = "\n".join(lines)
    print(text)
    with open(os.path.join(a.results, "timing.txt"), "w") as f:
        f.write(text + "\n")
    # the closing line CI and people read
    print("%s: %d passed, %d failed, %d skipped" % (a.title.split()[-1], t - fl - sk, fl, sk))
    if bad:
        print("%s: failed: %s (logs: %s/<suite>.log)" % (a.title, ", ".join(bad), a.results))
    return 1 if bad else 0


def dry_run():
    """make -n (or -t, -q) runs the recipe lines that call make, and so this script: it must
    then change nothing (no log truncated, no result removed) and only say what it would do."""
    words = os.environ.get("MAKEFLAGS", "").split()
    return bool(words) and not words[0].startswith("-") and "=" not in words[0] \
        and any(f in words[0] for f in "ntq")


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for n in ("start", "run", "summary"):
        p = sub.add_parser(n)
        p.add_argument("--results", required=True)
        if n == "run":
            p.add_argument("name")
            p.add_argument("command", nargs=argparse.REMAINDER)
        if n == "summary":
            p.add_argument("--title", required=True)
            p.add_argument("names", nargs="+")
    a = ap.parse_args(argv)
    if a.cmd == "run":
        if a.command and a.command[0] == "--":
            a.command = a.command[1:]
        if not a.command:
            ap.error("run: give the command after --")
    if dry_run():
        print("suite.py %s %s" % (a.cmd, " ".join(getattr(a, "command", []) or [])))
        return 0
    return {"start": cmd_start, "run": cmd_run, "summary": cmd_summary}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
