"""One configuration checked by spin: pan built (and cached), run with the search its
expectation needs (SEARCHES), its output read (stats, kind_of) and its trail replayed as a
readable trace; run_one gives the verdict. Standard library only (run.py runs under the
system python3)."""
import errno
import hashlib
import os
import re
import shutil
import signal
import subprocess
import threading
import time

from configs import bounded, bounded_memlim

HERE = os.path.dirname(os.path.abspath(__file__))
MODEL = os.path.join(HERE, "mip.pml")
# a configuration may name another model file of this folder (defs key "_MODEL")


def kind_of(text):
    """The property a pan/spin output reports violated."""
    if "acceptance cycle" in text:
        return "progress"
    m = re.search(r"assertion violated (.*)", text)
    if not m:
        return None
    for k in ("GAP", "MIX", "DUP_ORDER", "LOST", "SILENT", "DONE", "WARMFAIL", "DEADLOCK",
              "STUCK"):
        if re.search(r"\b%s\b" % k, m.group(1)):
            return k
    return "assert " + m.group(1)


def spin_defs(defs):
    out = []
    for k, v in defs.items():
        if not k.startswith("_"):
            out.append("-D%s=%s" % (k, v))
    return out


def model_of(defs):
    return os.path.join(HERE, defs["_MODEL"]) if "_MODEL" in defs else MODEL


def sh(cmd, cwd, timeout=900):
    p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       universal_newlines=True, timeout=timeout)
    return p.returncode, p.stdout


# How pan is compiled for each kind of search. -O1: the search runs as fast as with -O2 and
# the compile, most of a small configuration's time, takes 1.0 s instead of 1.7. No
# -DCOLLAPSE by default: it stores a state in about 0.7 of the memory but makes the search
# about 1.5 times as long; the largest configuration (10.3 M states) needs 2.0 GB without it.
# --collapse turns it on for variants whose state space would not fit --memlim otherwise.
CC_BASE = ["-O1", "-w"]
CC_COLLAPSE = ["-DCOLLAPSE"]
SEARCHES = {
    # progress (env.pml's never claim) under weak fairness, every assertion checked on the way
    "liveness": dict(cc=["-DNFAIR=3"], pan=["-a", "-f"]),
    # assertions only, breadth-first: the first violation found is a shortest one
    "safety": dict(cc=["-DBFS", "-DSAFETY", "-DNOCLAIM"], pan=[]),
    # assertions only, depth-first: for a violation deep in a large state space, where the
    # breadth-first search runs out of memory before it gets there (the trace is longer)
    "safety-dfs": dict(cc=["-DSAFETY", "-DNOCLAIM"], pan=[]),
}

# must-fail configurations whose violation lies too deep for the breadth-first search
DEPTH_FIRST = [r"^win2/bidi/"]


def search_for(expect, name=""):
    """The cheapest search that proves the expectation: a documented safety violation is
    found by the safety search alone; a known hang, and "holds" (progress and every
    assertion), by the progress search, whose claim (env.pml) leaves no state unvisited."""
    if expect.startswith("known:") and expect != "known:progress":
        return "safety-dfs" if any(re.search(rx, name) for rx in DEPTH_FIRST) else "safety"
    return "liveness"


def build(work, defs, extra_cc=(), cache=None, collapse=False):
    """spin -a and cc into work/pan; with cache, a pan built before from the same pan.c and
    flags is reused (the C compile is most of a small configuration's time)."""
    rc, out = sh(["spin", "-a"] + spin_defs(defs) + [model_of(defs)], work)
    if rc != 0 or not os.path.exists(os.path.join(work, "pan.c")):
        raise RuntimeError("spin -a failed:\n" + out)
    flags = CC_BASE + (CC_COLLAPSE if collapse else []) + list(extra_cc)
    key = None
    if cache:
        h = hashlib.sha256(" ".join(flags).encode())
        for f in sorted(os.listdir(work)):
            if f.startswith("pan.") and f[4:] in ("b", "c", "h", "m", "p", "t"):
                with open(os.path.join(work, f), "rb") as fh:
                    h.update(f.encode() + b"\0" + fh.read())
        key = os.path.join(cache, h.hexdigest()[:24])
        if os.path.exists(key):
            shutil.copy2(key, os.path.join(work, "pan"))
            return
    rc, out = sh(["cc"] + flags + ["-o", "pan", "pan.c"], work)
    if rc != 0:
        raise RuntimeError("cc pan.c failed:\n" + out)
    if key:
        os.makedirs(cache, exist_ok=True)
        tmp = key + ".%d.%d.tmp" % (os.getpid(), threading.get_ident())   # threads share the pid
        shutil.copy2(os.path.join(work, "pan"), tmp)
        os.replace(tmp, key)   # atomic: a parallel runner may write the same key


def stats(out):
    def grab(rx, conv=int, default=None):
        m = re.search(rx, out)
        return conv(m.group(1)) if m else default
    errors = grab(r"errors: (\d+)")
    why = None
    if "max search depth too small" in out:
        why = "max search depth too small"
    elif "reached -DMEMLIM bound" in out or "out of memory" in out:
        why = "out of memory (MODEL_MEMLIM)"
    elif errors == 0 and "Search not completed" in out:
        why = "search not completed"
    return {
        "stored": grab(r"(\d+) states, stored"),
        "depth": grab(r"depth reached (\d+)"),
        "errors": errors,
        # pan stops at the first error (then "not completed" is expected); without an error
        # only a search that covered every state proves anything
        "incomplete": why if (errors == 0 or errors is None) else None,
    }


SIDE = {"M0": "central(MDP)", "M1": "outstation(TRM)"}


def readable_trace(work, defs, limit=60):
    """Replays pan's trail with spin and keeps the model's own event lines."""
    model = model_of(defs)
    rc, out = sh(["spin", "-t", "-k", os.path.basename(model) + ".trail"] + spin_defs(defs)
                 + [model], work)
    lines = []
    for ln in out.splitlines():
        s = ln.strip()
        if s.startswith("@ "):
            s = s[2:]
            for k, v in SIDE.items():
                s = s.replace(k, v)
            s = s.replace("(t0#0)", "").replace("  ", " ").rstrip()
            lines.append(s)
        elif "START OF CYCLE" in s:
            lines.append("--- from here the run repeats forever (no progress) ---")
        elif "text of failed assertion" in s:
            lines.append("VIOLATED: " + s.split(":", 2)[-1].strip())
    # collapse immediate repeats
    packed = []
    for s in lines:
        if packed and packed[-1][0] == s:
            packed[-1][1] += 1
        else:
            packed.append([s, 1])
    text = ["%s%s" % (s, "" if n == 1 else "  (x%d)" % n) for s, n in packed]
    if len(text) > limit:
        text = text[:10] + ["... (%d lines left out)" % (len(text) - limit)] + text[-(limit - 10):]
    return text


def run_pan(cmd, cwd, timeout):
    """pan's output; at the timeout pan is interrupted (SIGINT), and then prints what it
    searched so far, as at any other stop."""
    # ETXTBSY: another thread's child, forked while this thread still had ./pan open for
    # writing (the copy from the cache), holds that descriptor until its exec; it is gone a
    # moment later
    for attempt in range(50):
        try:
            p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                 universal_newlines=True)
            break
        except OSError as e:
            if e.errno != errno.ETXTBSY or attempt == 49:
                raise
            time.sleep(0.05)
    try:
        return p.communicate(timeout=timeout)[0], False
    except subprocess.TimeoutExpired:
        p.send_signal(signal.SIGINT)
        try:
            out = p.communicate(timeout=30)[0]
        except subprocess.TimeoutExpired:
            p.kill()
            out = p.communicate()[0]
        return out + "\nSearch not completed\n", True


def run_one(name, defs, expect, work_root, maxdepth, memlim=4096, timeout=900, cache=None,
            collapse=False):
    work = os.path.join(work_root, re.sub(r"[^A-Za-z0-9]+", "_", name))
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    t0 = time.time()
    search = search_for(expect, name)
    sp = SEARCHES[search]
    if search.startswith("safety"):
        # look for the documented kind alone (env.pml: SEEK), so that another violation
        # found first cannot hide it
        defs = dict(defs, SEEK="K_" + expect.split(":", 1)[1])
    is_bounded = expect == "holds" and bounded(name)
    if is_bounded:
        memlim = bounded_memlim(name, memlim)
    build(work, defs, sp["cc"] + ["-DMEMLIM=%d" % memlim], cache, collapse)
    out, timed_out = run_pan(["./pan"] + sp["pan"] + ["-m%d" % maxdepth, "-w24"], work, timeout)
    st = stats(out)
    if timed_out and not st["errors"]:
        st["incomplete"] = "no result within %d s (--timeout)" % timeout
    kind = kind_of(out) if st["errors"] else None
    if kind and kind != "progress" and search == "liveness":
        # a safety violation where everything must hold: the shortest counterexample reads best
        build(work, defs, SEARCHES["safety"]["cc"] + ["-DMEMLIM=%d" % memlim], cache, collapse)
        sh(["./pan", "-m%d" % maxdepth, "-w24"], work, timeout=timeout)
    trace = readable_trace(work, defs) if kind else []
    secs = time.time() - t0
    if is_bounded and st["errors"] == 0 and st["incomplete"] and st["stored"]:
        ok = True
        verdict = "bounded: no violation in the first %d states (not a proof)" % st["stored"]
    elif expect == "holds":
        ok = st["errors"] == 0 and not st["incomplete"]
        verdict = ("INCOMPLETE (%s)" % st["incomplete"]) if (st["incomplete"] and not kind) else \
            ("holds" if ok else "VIOLATED " + (kind or "?"))
    else:
        want = expect.split(":", 1)[1]
        ok = kind == want
        if ok:
            verdict = "known weakness reproduced: " + want
        elif st["incomplete"] and not kind:
            verdict = "INCOMPLETE (%s): EXPECTED %s" % (st["incomplete"], want)
        else:
            verdict = "EXPECTED %s, got %s" % (want, kind or "no violation")
    return dict(name=name, stored=st["stored"], depth=st["depth"], secs=secs, ok=ok,
                verdict=verdict, kind=kind, trace=trace, raw=out, search=search)
