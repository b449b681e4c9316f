"""Exact-delivery check of a co-simulated run, from the programs' event taps.

Per stream (station s up to the central; with the bidirectional programs also the central
down to station s) the sender's events give its transfer attempts (records first..first+count-1
of a session, then done / failed with an error id / cut by a restart of the sender), the
receiver's events give the records it delivered. Demands:
- every record delivered is the logger's record, register for register (PLC_LogValue);
- every complete transfer at the receiver is exactly one attempt of the sender (no merged,
  shortened, reordered or invented transfer);
- every attempt the sender reports done arrived complete (nothing lost);
- an attempt that did not arrive was reported: the sender's xError (eErrorId), or it was cut
  by a restart of the sender and the receiver reported it (MIP_ERR_SENDER_RESET) or never saw it;
- at the end every sender has read out all its records and no transfer is open;
- without restarts: no failure at all, and each record arrives exactly once.
Warm restarts (LoggerLink.restart(..., warm=True)) roll a PLC back to its last snapshot: what its
taps logged after that snapshot is undone (the store and the logger lost it too) and is not
counted; with warm restarts only, the demands are those of a run without restarts.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from . import programs as L
from .sim import RESTART, WARM, LoggerLink


@dataclass
class StreamReport:
    name: str
    attempts: int = 0
    done: int = 0
    failed: Counter = field(default_factory=Counter)      # sender-reported errors by name
    cut: int = 0                                          # attempts cut by a sender restart
    receiver_failures: Counter = field(default_factory=Counter)
    lost_at_receiver_restart: int = 0
    transfers: int = 0                                    # complete at the receiver
    records: int = 0                                      # logger records in them
    registers: int = 0
    duplicated_records: int = 0                           # same logger record in two transfers
    delivered_after_failure: int = 0                      # complete transfers of failed/cut attempts
    lost: int = 0
    problems: list = field(default_factory=list)


def effective_events(events):
    """The events minus those a warm restart undid: at a WARM marker of PLC p, each tap of p
    is rolled back to the entry whose seq value (the entry's last word) is the restored one;
    the entries after it are dropped (with none such, all of that tap's entries are)."""
    out = []
    by_key = {}                       # (plc, tap) -> indexes into out
    for ev in events:
        if ev.tap == WARM:
            for tap, seq in zip(ev.words[0::2], ev.words[1::2]):
                idx = by_key.get((ev.plc, tap), [])
                while idx and out[idx[-1]].words[-1] != seq:
                    out[idx.pop()] = None
        elif ev.tap != RESTART:
            by_key.setdefault((ev.plc, ev.tap), []).append(len(out))
        out.append(ev)
    return [e for e in out if e is not None]


def _sender_attempts(events, pid, taps, total, per_transfer, sessions):
    """[(session, first, count, outcome)] from the sender taps of one PLC id."""
    attempts = []
    sess_iter = iter(sessions)
    session, pointer = next(sess_iter)
    for ev in events:
        if ev.plc != pid:
            continue
        if ev.tap == RESTART:
            if pointer < total:
                attempts.append((session, pointer + 1, _count(total, pointer, per_transfer), "cut"))
            session, pointer = next(sess_iter, (session, pointer))
            continue
        if ev.tap not in taps:
            continue
        flags, err = ev.words[0], ev.words[1]
        count = _count(total, pointer, per_transfer)
        if flags & 1:
            attempts.append((session, pointer + 1, count, "done"))
            pointer += count
        elif flags & 2:
            attempts.append((session, pointer + 1, count, "failed:" + L.error_name(err)))
    return attempts, pointer


def _count(total, pointer, per_transfer):
    left = total - pointer
    return min(left, per_transfer) if per_transfer else left


def _record(rep, name, open_tr, last, number, data):
    """One delivered record (PLC_RecordStore bit 0) of a stream: (open transfer, last number)."""
    if number == 1:
        if open_tr is not None:
            rep.problems.append(f"{name}: record 1 while a transfer was open, no failure reported")
        return [data] if any(data) else [], 1
    if open_tr is None:
        rep.problems.append(f"{name}: record {number} outside a transfer")
        return None, last
    if not (number == L.FFFF or number == last + 1):
        rep.problems.append(f"{name}: record {number} after {last}")
    if any(data):
        open_tr.append(data)
    return open_tr, number


def check_stream(chain: LoggerLink, name, sender, sender_tap, receiver, receiver_tap, station,
                 session_of, resumes):
    """session_of(sender session) -> the session word in the data. resumes: a restarted sender
    continues the same logger (a record is then the same record in every session)."""
    st = chain.s
    rep = StreamReport(name)
    payload = st.params(station, 1).effective_payload(st.bidi)
    total = st.records
    s_pid, r_pid = chain.ids[sender], chain.ids[receiver]
    sessions = [(session_of(x), start if isinstance(start, int) else start.get(station, 0))
                for x, start in chain.sessions[sender]]
    events = effective_events(chain.events)
    attempts, pointer = _sender_attempts(events, s_pid, {sender_tap}, total,
                                         st.per_transfer, sessions)
    rep.attempts = len(attempts)
    # receiver side: complete transfers
    complete = []
    open_tr = None
    last = 0
    for ev in events:
        if ev.plc != r_pid:
            continue
        if ev.tap == RESTART:
            if open_tr is not None:
                rep.lost_at_receiver_restart += 1
            open_tr, last = None, 0
            continue
        if ev.tap != receiver_tap:
            continue
        flags, number, length, err = ev.words[:4]
        data = ev.words[4:4 + length]
        if flags & 2:
            rep.receiver_failures[L.error_name(err)] += 1
            open_tr = None
        if flags & 1:
            open_tr, last = _record(rep, name, open_tr, last, number, data)
        if flags & 4:
            # the transfer completed (PLC_RecordStore bit 2, MIP_Receiver's xTransferEnd): its
            # 16#FFFF was accepted, delivered above if it had data; a transfer whose records
            # were all empty (an empty transfer) completes with none
            complete.append(open_tr or [])
            open_tr, last = None, L.FFFF
    if open_tr is not None:
        rep.problems.append(f"{name}: a transfer is still open at the receiver at the end")
    # content of every complete transfer
    keys = []
    seen = Counter()
    for tr in complete:
        ns = []
        for rec in tr:
            n = rec[0] + (rec[1] << 16) if len(rec) > 1 else rec[0]
            sess = rec[2] if len(rec) > 2 else None
            want = L.log_record(n, payload, sess if sess is not None else 0, station)
            if rec[:payload] != want or any(rec[payload:]):
                rep.problems.append(f"{name}: record n={n} session={sess} differs from the "
                                    f"logger's: got {rec[:8]}..., want {want[:8]}...")
            ns.append((sess, n))
        if ns and any(ns[i][1] != ns[0][1] + i or ns[i][0] != ns[0][0] for i in range(len(ns))):
            rep.problems.append(f"{name}: transfer not consecutive: {ns[:4]}...")
        for k in ns:
            seen[k[1] if resumes else k] += 1
        rep.registers += sum(len(r) for r in tr)
        keys.append((ns[0][0], ns[0][1], len(ns)) if ns else (None, 0, 0))
    rep.transfers = len(complete)
    rep.records = sum(k[2] for k in keys)
    rep.duplicated_records = sum(c - 1 for c in seen.values() if c > 1)
    # match complete transfers to attempts
    used = [False] * len(attempts)
    for key in keys:
        # a range is done at most once (the read-out pointer then moves on); earlier failed
        # attempts of the same range may have arrived too (the failure was on the way back)
        cands = [i for i, a in enumerate(attempts) if not used[i] and a[:3] == key]
        done = [i for i in cands if attempts[i][3] == "done"]
        if not cands:
            rep.problems.append(f"{name}: complete transfer {key} matches no attempt of the sender")
            continue
        i = done[0] if done else cands[0]
        used[i] = True
        if attempts[i][3] != "done":
            rep.delivered_after_failure += 1
    for i, a in enumerate(attempts):
        if a[3] == "done":
            rep.done += 1
            if not used[i]:
                rep.lost += 1
                rep.problems.append(f"{name}: LOST: the sender reported {a[:3]} done, "
                                    "the receiver has no such complete transfer")
        elif a[3] == "cut":
            rep.cut += 1
        else:
            rep.failed[a[3].split(":", 1)[1]] += 1
    if pointer < total:
        rep.problems.append(f"{name}: only {pointer} of {total} records read out")
    restarts = [w for _, w in chain.restarts]
    if not restarts:
        if rep.failed or rep.cut or rep.receiver_failures or rep.duplicated_records:
            rep.problems.append(f"{name}: failures without restarts: sender {dict(rep.failed)}, "
                                f"receiver {dict(rep.receiver_failures)}, "
                                f"duplicated records {rep.duplicated_records}")
    return rep


def check(chain: LoggerLink):
    reps = []
    for s in range(1, chain.s.stations + 1):
        reps.append(check_stream(chain, f"station {s} -> central", ("out", s), 20 + s,
                                 ("cen", 0), s, s, lambda x: x, True))
        if chain.s.bidi:
            reps.append(check_stream(chain, f"central -> station {s}", ("cen", 0), 10 + s,
                                     ("out", s), 30 + s, s, lambda x: x ^ 0x8000, True))
    return reps


def summary(reps):
    tot = Counter()
    for r in reps:
        tot["transfers"] += r.transfers
        tot["records"] += r.records
        tot["registers"] += r.registers
        tot["lost"] += r.lost
        tot["duplicated"] += r.duplicated_records
        tot["failed_reported"] += sum(r.failed.values())
        tot["cut_by_restart"] += r.cut
        tot["receiver_reports"] += sum(r.receiver_failures.values())
        tot["delivered_after_failure"] += r.delivered_after_failure
        tot["problems"] += len(r.problems)
    return dict(tot)
