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

usage: model/run.py [-k SUBSTRING] [--quick] [--list] [--junit FILE] [--trace-dir DIR] [--work DIR]
"""
import argparse
import concurrent.futures
import errno
import hashlib
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from xml.sax.saxutils import escape

HERE = os.path.dirname(os.path.abspath(__file__))
MODEL = os.path.join(HERE, "mip.pml")
# a configuration may name another model file of this folder (defs key "_MODEL")

# name, defines, expectation, what it shows
#   expectation: "holds" or "known:<kind>" with kind one of
#   progress (a run in which the sender never finishes: no error, no completion),
#   MIX, DUP_ORDER, GAP, LOST, SILENT, DONE (the assertion names in env.pml)
NOTE_CONFIGS = [
    ("note-note/strict/spont", dict(SND="NOTE", RCV="NOTE"), "holds",
     "two note peers, no restart: everything arrives"),
    ("note-note/strict/polled", dict(SND="NOTE", RCV="NOTE", POLLED=1), "holds",
     "two note peers, polled drive"),
    ("note-note/strict/spont/down", dict(SND="NOTE", RCV="NOTE", SSIDE=0), "holds",
     "two note peers, the central sends to the outstation"),
    ("note-note/lenient/spont", dict(SND="NOTE", RCV="NOTE", NS_LENIENT=1, NR_LENIENT=1), "holds",
     "two lenient note peers, no restart"),
]

def _matrix():
    out = []
    drives = [("spont", {}), ("polled", {"POLLED": 1})]
    sides = [("up", {}), ("down", {"SSIDE": 0})]
    faults = [("", {}), ("+rst-snd", {"RST_S": 1}), ("+rst-rcv", {"RST_R": 1})]
    peers = [
        ("ours-ours", {"SND": "OURS", "RCV": "OURS"}),
        ("ours-noteR-strict", {"SND": "OURS", "RCV": "NOTE"}),
        ("ours-noteR-lenient", {"SND": "OURS", "RCV": "NOTE", "NR_LENIENT": 1}),
        ("noteS-strict-ours", {"SND": "NOTE", "RCV": "OURS"}),
        ("noteS-lenient-ours", {"SND": "NOTE", "RCV": "OURS", "NS_LENIENT": 1}),
        ("note-note-strict", {"SND": "NOTE", "RCV": "NOTE"}),
        ("note-note-lenient", {"SND": "NOTE", "RCV": "NOTE", "NS_LENIENT": 1, "NR_LENIENT": 1}),
    ]
    # bidirectional layout (MIP_Link, note 2.2): one transfer and one write of the other
    # stream per side (each more multiplies the states by about 3); "bidi-noC3" drops
    # configuration rule C3 (PROTOCOL.md P9: each side reads once per poll cycle)
    layouts = [("", {}), ("bidi/", {"BIDI": 1, "NBW": 1, "NT": 1})]
    for ln, ld in layouts:
        for pn, pd in peers:
            for dn, dd in drives:
                for sn, sd in sides:
                    for fn, fd in faults:
                        d = dict(pd); d.update(dd); d.update(sd); d.update(fd); d.update(ld)
                        if fd:
                            d["NT"] = 1   # a restart makes the second attempt itself
                        name = "%s%s/%s/%s%s" % (ln, pn, dn, sn, fn)
                        exp, why = expectation(name)
                        out.append((name, d, exp, why))
    # warm restarts with rollback to the last snapshot (issue 16, PROTOCOL.md W1..W3): our
    # blocks, durable before visible (DURABLE=1) must lose, duplicate and fail nothing, also
    # against note peers; with periodic snapshots only (DURABLE=0) the model must find the loss
    warm = [("+wrst-snd", {"WRST_S": 1}), ("+wrst-rcv", {"WRST_R": 1}),
            ("+wrst-both", {"WRST_S": 1, "WRST_R": 1})]
    for pn, pd in peers[:5]:
        for dn, dd in drives:
            for sn, sd in sides:
                for fn, fd in warm:
                    if ("WRST_S" in fd and pd["SND"] == "NOTE") or ("WRST_R" in fd and pd["RCV"] == "NOTE"):
                        continue   # a note peer has no retained state: its restarts are the cold ones
                    for durn, durd in (("", {}), ("/periodic", {"DURABLE": 0})):
                        if durn and (pn != "ours-ours" or fn == "+wrst-both"):
                            continue   # W0 is shown by one side's rollback at a time
                        d = dict(pd); d.update(dd); d.update(sd); d.update(fd); d.update(durd)
                        name = "warm%s/%s/%s/%s%s" % (durn, pn, dn, sn, fn)
                        exp, why = expectation(name)
                        out.append((name, d, exp, why))
    # warm restarts in the bidirectional layout (MIP_Link, PROTOCOL.md W4): our link against
    # our link and against note peers; one write of the other stream per side, which with the
    # gate carries only state a snapshot holds
    for pn, pd in peers[:5]:
        for dn, dd in drives:
            for fn, fd in warm[:2]:   # +wrst-both: 22 M states, 3.3 GB, 3 min each (docs/dev/model.md)
                if ("WRST_S" in fd and pd["SND"] == "NOTE") or ("WRST_R" in fd and pd["RCV"] == "NOTE"):
                    continue
                d = dict(pd); d.update(dd); d.update(fd); d.update({"BIDI": 1, "NBW": 1, "NT": 1})
                name = "warm/bidi/%s/%s/up%s" % (pn, dn, fn)
                exp, why = expectation(name)
                out.append((name, d, exp, why))
    # without the gate (LINKGATE=0) the other part's write carries a record or an
    # acknowledgement no snapshot holds: the model must find the failure
    for fn, fd in warm[:2]:
        d = {"SND": "OURS", "RCV": "OURS", "BIDI": 1, "NBW": 1, "NT": 1, "LINKGATE": 0}
        d.update(fd)
        name = "warm-nogate/bidi/ours-ours/spont/up%s" % fn
        exp, why = expectation(name)
        out.append((name, d, exp, why))
    # a master that reads the read area in parts (issue 38, plcrt's status_first; env.pml
    # SPLITREAD): warm restarts of our pair. Data only with bit 0 (SPLITREAD=1) must fail, also
    # when the image holds no block or its counter differs (2, the runtime's rule) must hold
    for fn, fd in warm[:2]:
        for vn, v in (("", 2), ("-bit0", 1)):
            d = {"SND": "OURS", "RCV": "OURS", "SPLITREAD": v}
            d.update(fd)
            name = "warm-split%s/ours-ours/spont/up%s" % (vn, fn)
            exp, why = expectation(name)
            out.append((name, d, exp, why))
    # the pipelined sender (issue 15, PROTOCOL.md P27: window 2): our sender against our
    # receiver and the note receivers, spontaneous drive, 5 records per transfer (the window
    # opens from record 2 on and closes before 16#FFFF: records 3 and 4 go up before the
    # acknowledgement of the one before; after a repeat it opens again one acknowledged
    # record later, PIPE_CLOSE=1); and the variants the rule excludes, which must fail
    for pn, pd in peers[:3]:
        for sn, sd in sides:
            for fn, fd in faults:
                d = dict(pd); d.update(sd); d.update(fd)
                d.update({"WIN": 2, "NREC": 5})
                if fd:
                    d["NT"] = 1
                name = "win2/%s/spont/%s%s" % (pn, sn, fn)
                exp, why = expectation(name)
                out.append((name, d, exp, why))
    # the pipelined sender retained (PROTOCOL.md P27 with W1/W3): warm restarts of our sender
    # (and of our receiver, and both) with window 2, against our receiver and the note
    # receivers; the pipelined record is durable before it is visible (PC_PIPE) and the
    # pipelined state is part of the snapshot. Without either the model must find the failure
    for pn, pd in peers[:3]:
        for sn, sd in sides:
            for fn, fd in warm:
                if "WRST_R" in fd and pd["RCV"] == "NOTE":
                    continue   # a note peer has no retained state
                d = dict(pd); d.update(sd); d.update(fd)
                d.update({"WIN": 2, "NREC": 5})
                name = "warm/win2/%s/spont/%s%s" % (pn, sn, fn)
                exp, why = expectation(name)
                out.append((name, d, exp, why))
    for vn, vd in (("nogate", {"PIPEGATE": 0}), ("norestore", {"PIPERESTORE": 0})):
        d = {"SND": "OURS", "RCV": "OURS", "WIN": 2, "NREC": 5, "WRST_S": 1}
        d.update(vd)
        name = "warm-win2-%s/ours-ours/spont/up+wrst-snd" % vn
        exp, why = expectation(name)
        out.append((name, d, exp, why))
    # window 2 in the bidirectional layout is withdrawn (MIP_Link runs window 1): the rule as
    # it was loses a record after a restart of our sender. 4 records per transfer: the
    # shortest case (record 3 pipelined, 16#FFFF after it); with 5 records the same needs a
    # longer run than a search finds in CI's time
    # (the central sending, down, shows no violation of any kind in its 39 M states with 4
    # records: one refutation is enough to withdraw the rule)
    d = {"SND": "OURS", "RCV": "OURS", "BIDI": 1, "NBW": 1, "NT": 1, "WIN": 2, "NREC": 4,
         "RST_S": 1}
    name = "win2/bidi/ours-ours/spont/up+rst-snd"
    exp, why = expectation(name)
    out.append((name, d, exp, why))
    for vn, vd, fn, fd in (("pipefirst", {"PIPE_FIRST": 1}, "+rst-snd", {"RST_S": 1, "NT": 1}),
                           ("pipelast", {"PIPE_LAST": 1}, "", {}),
                           ("pipekeep", {"PIPE_KEEP": 1, "RCV": "NOTE"}, "", {})):
        d = {"SND": "OURS", "RCV": "OURS", "WIN": 2, "NREC": 4}
        d.update(vd); d.update(fd)
        name = "win2-%s/ours-%s/spont/up%s" % (vn, "noteR-strict" if d["RCV"] == "NOTE" else "ours", fn)
        exp, why = expectation(name)
        out.append((name, d, exp, why))
    for dn, dd in drives:
        for fn, fd in faults[1:]:
            d = {"SND": "OURS", "RCV": "OURS", "BIDI": 1, "NBW": 1, "NT": 1, "C3": 0}
            d.update(dd); d.update(fd)
            name = "bidi-noC3/ours-ours/%s/up%s" % (dn, fn)
            exp, why = expectation(name)
            out.append((name, d, exp, why))
    # the hand-over at the central (issue 35, model/handover.pml): the radio acknowledgement
    # after the control system took the record, with restarts of the central between receipt
    # and hand-over; acknowledging first (ACK_FIRST) must lose a record at a cold restart
    for rule, rd in (("ack-after", {}), ("ack-first", {"ACK_FIRST": 1})):
        for rn, r in (("none", {"RST": 0}), ("cold", {"RST": 1, "COLD": 1}),
                      ("cold2", {"RST": 2, "COLD": 1}), ("warm", {"RST": 1, "COLD": 0}),
                      ("warm2", {"RST": 2, "COLD": 0})):
            if rule == "ack-first" and rn.endswith("2"):
                continue
            d = {"_MODEL": "handover.pml"}
            d.update(rd); d.update(r)
            name = "handover/%s/%s" % (rule, rn)
            exp, why = expectation(name)
            out.append((name, d, exp, why))
    return out


# Documented weaknesses (see docs/dev/model.md): (regular expression over the name, kind, why).
# Everything else must hold.
KNOWN = [
    (r"^(bidi/)?note-note-.*\+rst-snd$", "MIX",
     "N1: a restarted note sender counts the stale acknowledgement of the old record 1"),
    (r"^(bidi/)?note-note-strict/.*\+rst-rcv$", "progress",
     "N2: a restarted strict note receiver waits for record 1, the sender repeats forever, silently"),
    (r"^(bidi/)?note-note-lenient/.*\+rst-rcv$", "SILENT",
     "N3: a lenient note receiver drops an open transfer without an error"),
    (r"^(win2/)?ours-noteR-.*\+rst-snd$", "MIX",
     "F2: a note receiver takes our restarted sender's record 1 for a duplicate; its ack has no echo"),
    (r"^(win2/)?bidi/ours-noteR-.*\+rst-snd$", "MIX",
     "F2 (bidirectional): a note receiver takes our restarted sender's record 1 for a duplicate "
     "and acknowledges it; once our block reached its modem (P9) the acknowledgement counts"),
    (r"^(bidi/)?noteS-.*-ours/.*\+rst-snd$", "MIX",
     "F3: a restarted note sender counts a stale acknowledgement; its new record 1 never goes on air"),
    (r"^(bidi/)?noteS-lenient-ours/.*\+rst-rcv$", "GAP",
     "F4: a sender that goes back to record 1 on ack 0 then counts a stale acknowledgement"),
    (r"^warm/periodic/.*\+wrst-snd$", "WARMFAIL",
     "W0: without W1 a sender rolled back to an older snapshot sends a record the receiver "
     "has passed: it takes it for a sender restart, the transfer fails and is sent again"),
    (r"^warm/periodic/.*\+wrst-rcv$", "DONE",
     "W0: without W2 a receiver rolled back to an older snapshot has lost a transfer it "
     "acknowledged complete: the sender reported done, the data are gone"),
    (r"^win2/bidi/ours-ours/spont/up\+rst-snd$", "GAP",
     "P27 withdrawn in the bidirectional layout: after a restart of our sender a stale "
     "acknowledgement of record 1 counts (the P9 residual), and the peer's writes still carry "
     "its number of the old session when it equals the pipelined record: counted for two "
     "records, 16#FFFF overwrites the second in the own modem"),
    (r"^warm-split-bit0/.*\+wrst-rcv$", "MIX",
     "issue 38: a master that reads the rest of the block only with bit 0 gives a receiver "
     "killed while a read's answer was on the line (bit 0 taken) the next counter with data "
     "of no read: it accepts and acknowledges a record without its data"),
    (r"^handover/ack-first/cold$", "LOST",
     "issue 35: a central that acknowledges a record over the radio on receipt and restarts "
     "cold before it handed the record to the control system loses it: the outstation has "
     "deleted it, the control system never gets it"),
    (r"^warm-nogate/", "WARMFAIL",
     "W4: without the link's gate the other part's write carries a record or an "
     "acknowledgement no snapshot holds; after the rollback the two sides are out of step "
     "and the open transfer fails"),
    (r"^warm-win2-nogate/", "WARMFAIL",
     "P27 with W1: the pipelined record written before a snapshot holds it; a warm restart "
     "rolls the sender back to the record before it, which the receiver has passed: the "
     "sender takes the acknowledgement of the pipelined record for out of step and fails "
     "the transfer, which is sent again (a duplicate)"),
    (r"^warm-win2-norestore/", "WARMFAIL",
     "P27 with W3: the snapshot without the pipelined state (ahead, sent2): after a warm "
     "restart the sender waits for the older record only, the receiver acknowledges the "
     "pipelined one, the sender takes it for out of step and fails the transfer"),
    (r"^win2-pipefirst/", "MIX",
     "P27: record 2 pipelined before record 1 was acknowledged: a stale acknowledgement 2 of "
     "the restarted sender's old session counts for records 1 and 2"),
    (r"^win2-pipelast/", "GAP",
     "P27: the last record pipelined: it overwrites the unread record before it in the peer's "
     "modem, and a receiver takes 16#FFFF after any number"),
    (r"^win2-pipekeep/", "progress",
     "P27: the window stays open after a repeat: a receiving PLC slower than the radio sees "
     "each record overwritten by the pipelined next one, ignores it, and the sender repeats "
     "forever (our receiver would report the peer out of step)"),
    (r"^(win2/)?bidi-noC3/ours-.*\+rst-snd$", "MIX",
     "P9 residual without C3: a stale acknowledgement counted after record 1 reached the peer's "
     "modem; record 2 overwrites the unread record 1 (C3 closes it: bidi/ours-ours/* hold)"),
]


# Configurations whose whole state space does not fit a search on CI's machine run a bounded
# search (as much of the state space as --memlim holds; the verdict says "bounded", not a
# proof). The four there were (window 2 in the bidirectional layout with a restart) went with
# that rule. The retained pipelined sender against our receiver with a warm restart of the
# sender: 47 to 55 M states, beyond 4 GB; the whole search holds with --collapse --memlim 9000
# (8 to 11 min each); with warm restarts of both sides it did not finish within 8.5 GB
# (docs/dev/model.md "The pipelined sender, retained")
# The third field caps such a search's memory below --memlim (MB): half the state space of a
# search that stops anyway costs make check half the time (13 M states in about 50 s here).
BOUNDED = [(r"^warm/win2/ours-ours/spont/(up|down)\+wrst-(snd|both)$",
            "window 2, warm restart of the sender, our receiver: 47 M states and more", 2048)]

def bounded(name):
    return any(re.search(rx, name) for rx, _, _ in BOUNDED)


def bounded_memlim(name, memlim):
    """The memory bound of a bounded configuration's search: its own cap, if lower."""
    caps = [cap for rx, _, cap in BOUNDED if re.search(rx, name)]
    return min([memlim] + caps)


def expectation(name):
    for rx, kind, why in KNOWN:
        if re.search(rx, name):
            return "known:" + kind, why
    return "holds", ""


CONFIGS = _matrix()

# The SIPROTEC event-recorder handshake at the outstation (issue 35, model/soe.pml): a relay,
# MIP_SoeReader and its logger; "acknowledge after store" loses nothing (LOST, GAP), and with
# warm restarts delivers exactly once (DUP_ORDER). Lost answers (LOSS) and restarts (RST).
SOE_CONFIGS = [
    ("soe/cold", dict(_MODEL="soe.pml", RST=2, LOSS=3), "holds",
     "ack after store, cold restarts and lost answers: nothing lost, no gap (duplicates allowed)"),
    ("soe/warm", dict(_MODEL="soe.pml", WARM=1, RST=2, LOSS=3), "holds",
     "ack after a snapshot holds the stored entries, warm restarts: exactly once, in order"),
    ("soe/blk3", dict(_MODEL="soe.pml", BLK=3, N=5, SEQB=2, RST=1, LOSS=2), "holds",
     "three message blocks per read as the relay, five events, sequence numbers wrap"),
    ("soe-ackearly/cold", dict(_MODEL="soe.pml", ACK_EARLY=1, LOSS=0, RST=1), "known:LOST",
     "acknowledge before store: a cold restart between the acknowledgement and the store loses "
     "the entries the relay already deleted"),
    ("soe-nogate/warm", dict(_MODEL="soe.pml", WARM=1, NOGATE=1, RST=1, LOSS=0), "known:LOST",
     "warm restarts without the snapshot gate: the PLC comes back with a store older than "
     "the acknowledgement"),
    ("soe-relay/cold", dict(_MODEL="soe.pml", RRST=2, RST=1, LOSS=2), "holds",
     "two relay restarts (recorder emptied, number 0) with events right after them: a number 1 "
     "seen twice the same is taken as a restarted relay; nothing lost but the relay's own"),
    ("soe-relay/warm", dict(_MODEL="soe.pml", RRST=1, WARM=1, RST=2, LOSS=2), "holds",
     "a relay restart among warm restarts of the PLC: exactly once, in order, but the relay's own"),
    ("soe-nodetect/cold", dict(_MODEL="soe.pml", RRST=1, NODETECT=1, LOSS=0, RST=0), "known:STUCK",
     "without the restart rule the reader rejects a restarted relay's reads for good"),
    ("soe-relayack1/cold", dict(_MODEL="soe.pml", RRST=1, RR_ANY=1, VERIFY=0, LOSS=0, RST=0),
     "known:LOST",
     "without the verify read: an open read numbered 1 across a relay restart; its "
     "acknowledgement is taken by the restarted relay for its own first read and deletes new entries"),
    ("soe-verify/cold", dict(_MODEL="soe.pml", RRST=1, RR_ANY=1, LOSS=2, RST=1), "holds",
     "the verify read before acknowledging a read numbered 1: a relay restart at any point, "
     "lost answers, a cold PLC restart: nothing lost but the relay's own"),
    ("soe-verify/warm", dict(_MODEL="soe.pml", RRST=1, RR_ANY=1, WARM=1, LOSS=1, RST=2), "holds",
     "the verify read with warm PLC restarts (the open read numbered 1 back from a snapshot): "
     "exactly once, in order, but the relay's own"),
    ("soe-verify-inflight/warm", dict(_MODEL="soe.pml", RRST=1, RR_ANY=1, WARM=1, RDETECT=0, LOSS=0,
                                      RST=1), "known:LOST",
     "the verify read, but a warm PLC restart from a snapshot taken while the acknowledgement "
     "was in flight sends it again without a new verify read, after the relay restarted"),
    ("soe-verify-nowin/cold", dict(_MODEL="soe.pml", RRST=1, RR_ANY=1, VWIN=0, LOSS=0, RST=0),
     "known:LOST",
     "the verify read, but the relay restarts and records between its answer and the "
     "acknowledgement's arrival: what the verify read relies on"),
]
CONFIGS += SOE_CONFIGS

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


# make test's quick set: one configuration of each family, cheap ones, and must-fail ones of
# both searches, so both kinds of search and both layouts run on every change (make check
# runs them all)
QUICK = [
    "note-note-strict/spont/up",                  # two note peers
    "note-note-strict/spont/up+rst-rcv",          # must fail: a silent hang (progress, N2)
    "ours-ours/spont/up+rst-rcv",                 # our pair, receiver restart
    "ours-noteR-strict/polled/down+rst-snd",      # must fail: MIX (F2), safety search
    "noteS-lenient-ours/spont/up+rst-rcv",        # must fail: GAP (F4)
    "bidi/note-note-strict/spont/up+rst-rcv",     # bidirectional layout, must fail: N2
    "bidi-noC3/ours-ours/polled/up+rst-snd",      # our link, must fail: P9 residual without C3
    "warm/ours-ours/polled/up+wrst-rcv",          # warm restart of our receiver
    "warm/periodic/ours-ours/spont/up+wrst-rcv",  # must fail: W0 (DONE)
    "warm-nogate/bidi/ours-ours/spont/up+wrst-rcv",  # must fail: W4 (WARMFAIL), our link
    "win2/ours-ours/spont/up",                    # the pipelined sender
    "win2-pipelast/ours-ours/spont/up",           # must fail: P27 (GAP)
    "warm-split-bit0/ours-ours/spont/up+wrst-rcv",  # must fail: a read in parts with bit 0 alone (issue 38)
    "soe/warm",                                   # the SOE handshake (issue 35), warm restarts
    "soe-relay/cold",                             # a restarted relay taken up by the reader
    "soe-verify/cold",                            # the verify read before acknowledging a read numbered 1
    "soe-ackearly/cold",                          # must fail: acknowledge before store (LOST)
    "handover/ack-after/cold",                    # the hand-over at the central (issue 35)
    "handover/ack-first/cold",                    # must fail: acknowledged before the hand-over (LOST)
]


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
                    help="only the quick set: one configuration of each family (make test)")
    ap.add_argument("--timeout", type=int, default=1200,
                    help="seconds one search may take before it counts as INCOMPLETE (default 1200)")
    ap.add_argument("--memlim", type=int, default=int(os.environ.get("MODEL_MEMLIM", "4096")),
                    help="MB one search may use before it counts as INCOMPLETE (default 4096, "
                         "or MODEL_MEMLIM)")
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
           and not any(x in n for x in a.x)]
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
                           a.collapse)
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
        print("model: %d of the passed are bounded searches, not proofs (model/run.py BOUNDED)"
              % nbounded)
    print("model: %d passed, %d failed" % (npass, nfail))
    return 0 if nfail == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
