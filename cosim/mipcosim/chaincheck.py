"""The chain's check (issue 35): every relay event at the control system exactly once, in order,
with its original time stamp and value; the relay's recorder empty (mipcosim.chain.SoeChain)."""
from __future__ import annotations

from dataclasses import dataclass

from .chainprograms import expected


@dataclass
class ChainReport:
    events: int            # relay events scripted
    taken: int             # entries the SCADA took (duplicates included)
    lost: int              # events that never reached the control system
    duplicated: int        # entries taken more than once
    restart_duplicates: int  # of them: a restart of the central between the two copies that
                             # explains it (cold; push: also kill -9, see check_chain)
    changed: int           # entries taken that the relay never had (a field changed)
    out_of_order: int      # entries taken before an earlier event's first arrival
    relay_left: int        # entries still in the relay's recorder
    relay_dropped: int     # entries the relay dropped (its recorder overflowed)
    lost_at_relay: int     # events a relay restart took before the outstation had them
    problems: list


def check_chain(ch) -> ChainReport:
    """Every relay event at the control system exactly once, in order, with its original time
    stamp and value, and the relay's recorder empty. Pull: the SCADA's entries (all four words,
    the time stamp in ms). Push: what each driver of the pair received (WinCC OA keeps no cause /
    type, and time stamps of 10 ms): an event counts as arrived when either driver has it, and
    each driver must have it once and in order."""
    exp = expected(ch.s.events)
    if ch.push:
        exp = [(e[0], e[1], None, e[3], e[4] // 10 * 10) for e in exp]
    index = {e: i for i, e in enumerate(exp)}
    seen = {}        # (group, event) -> its first row; a group: the SCADA, or one driver
    anywhere = set()
    changed = dup = disorder = rst_dup = 0
    last = {}
    problems = []
    for n, r in enumerate(ch.rows):
        g = r.get("driver", "scada")
        key = (r["type_bit"], r["address"], r["cause_type"], r["value"], r["ts_ms"])
        i = index.get(key)
        if i is None:
            changed += 1
            if changed <= 3:
                problems.append(f"entry {n + 1} at the control system was never in the relay: {key}")
            continue
        if (g, i) in seen:
            dup += 1
            t0, t1 = ch.taken_at[seen[g, i]], ch.taken_at[n]
            # a cold central forgot it had handed the record over; a pushing central killed
            # (kill -9) after a driver took a frame and before a snapshot recorded it writes the
            # frame again: MIP_UnicosEvents cannot know, and WinCC OA has no sequence number to
            # tell it (the SCADA of the pull way has: its SOE_Control sequence number)
            kinds = ("cold", "warm") if ch.push else ("cold",)
            if any(who == "cen" and kind in kinds and t0 <= t <= t1 for t, who, kind in ch.restarts):
                rst_dup += 1
            elif dup - rst_dup <= 3:
                by = f" by driver {g.upper()}" if g != "scada" else ""
                problems.append(f"event {i + 1} taken twice{by} (entries {seen[g, i] + 1} and "
                                f"{n + 1}), no restart of the central between them that explains it")
            continue
        seen[g, i] = n
        anywhere.add(i)
        if i < last.get(g, -1):
            disorder += 1
            if disorder <= 3:
                problems.append(f"event {i + 1} arrived after event {last[g] + 1}")
        last[g] = max(last.get(g, -1), i)
    gone = [i for i in range(len(exp)) if i not in anywhere]
    at_relay = sum(1 for i in gone if i in ch.at_risk)
    lost = len(gone) - at_relay
    if lost:
        first = next(i for i in gone if i not in ch.at_risk)
        problems.append(f"{lost} event(s) never reached the control system (the first: event "
                        f"{first + 1}, {exp[first]})")
    st = ch.relay_stats()
    if st["entries"]:
        problems.append(f"the relay still holds {st['entries']} entries")
    if st["dropped"]:
        problems.append(f"the relay dropped {st['dropped']} entries (recorder full)")
    return ChainReport(len(exp), len(ch.rows), lost, dup, rst_dup, changed, disorder, st["entries"],
                       st["dropped"], at_relay, problems)
