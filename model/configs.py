"""The configurations of the spin model (run.py checks them): the families of the matrix,
what each must show (KNOWN: the documented weaknesses; everything else must hold), the ones
searched bounded (BOUNDED) and make test's quick set (QUICK). Standard library only: run.py
runs under the system python3."""
import re

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
# The third field caps such a search's memory below --memlim (MB) in make check: a search that
# stops anyway costs in proportion to what it stores. 512 MB: 2.9 M states, about 20 s of CPU
# each (2048 MB, 11 M states, took 94 to 134 s each of make check's 29 min in CI beside the
# Python tests); `make model-deep` lifts the cap (--bounded-memlim 0) for the whole searches.
BOUNDED = [(r"^warm/win2/ours-ours/spont/(up|down)\+wrst-(snd|both)$",
            "window 2, warm restart of the sender, our receiver: 47 M states and more", 512)]


# Configurations make check leaves to `make check-large` (CI runs both, one after the other):
# the largest searches, which together take about two thirds of the model's time (measured in
# CI's make check: about 2000 of 3060 s of searching) and would put make check over its 25
# minutes on 2 cores. Our choice; every configuration stays a proof CI runs before a change
# lands, and the quick set (QUICK) stays in make test and make check whatever this list says.
# (regular expression over the name, why it is large)
LARGE = [
    (r"^warm/bidi/", "warm restarts in the bidirectional layout: 1.5 to 9 M states each"),
    (r"^warm/win2/", "the pipelined sender retained: up to 55 M states (searched bounded)"),
    (r"^bidi(-noC3)?/ours-.*\+rst-", "our link sending, with a restart: up to 4 M states each"),
    (r"^win2/ours-ours/.*\+rst-", "the pipelined sender with a restart, our receiver"),
    (r"^warm/ours-ours/.*\+wrst-both$", "warm restarts of both sides of our pair"),
    (r"^bidi/noteS-strict-ours/.*\+rst-rcv$",
     "the note's strict sender against our link with a restart: 15 to 21 s each"),
]


def large(name):
    """In make check-large's tier instead of make check's (LARGE); never a quick one."""
    return name not in QUICK and any(re.search(rx, name) for rx, _ in LARGE)


def bounded(name):
    return any(re.search(rx, name) for rx, _, _ in BOUNDED)


def bounded_memlim(name, memlim, cap=None):
    """The memory bound of a bounded configuration's search: its own cap (or `cap`, if given;
    0: no cap), if lower than memlim."""
    caps = [cap if cap is not None else c for rx, _, c in BOUNDED if re.search(rx, name)]
    return min([memlim] + [c for c in caps if c > 0])


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
