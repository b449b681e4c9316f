"""The chain's fault (issue 44): for a network with a relay and a control system (WinCC OA's
UNICOS driver or a SCADA), the events that did not arrive once and the hop where they stopped,
from what each hop saw: the relay (which entries its reader took: it lets them go in order),
the receivers of the PLCs (the records they delivered, kit/mipkit/delivery.py), the MIP
blocks' diagnosis at the end (report.Observer) and the control system's own list.

The hops, in order: relay -> reader -> logger -> sender -> radio -> receiver -> hand-over ->
control system.
"""
from __future__ import annotations

import collections
from dataclasses import dataclass

import json

from .report import SEC, _window_lines, display_path, enum_name, observer

# the sender's waits that mean its record is out on the radio (no acknowledgement yet)
_ON_THE_RADIO = {"MIP_WAIT_ACK", "MIP_WAIT_REQUEST", "MIP_WAIT_CONFIRM", "MIP_WAIT_OUT_OF_STEP"}


@dataclass
class ChainFault:
    line: str           # the report's first line, without "mip-kit: fault: "
    t: int              # the moment to centre the diagram on (virtual ns)
    station: int = 1


def _ends(net):
    from .ends import KitRelay, KitScada, KitUnicos
    relays = [e for e in net.ends.values() if isinstance(e, KitRelay)]
    fars = [e for e in net.ends.values() if isinstance(e, (KitUnicos, KitScada))]
    return relays, fars


def _delivered(net):
    """Counter of the 8-word entries the PLCs' MIP_Receivers delivered, and who delivered them."""
    have, who = collections.Counter(), {}
    for kp in net.plcs.values():
        taps = getattr(kp, "_taps", None)
        if taps is None:
            continue
        for path, rec in taps.by_path.items():
            for payload in rec.records:
                for i in range(0, len(payload) - len(payload) % 8, 8):
                    k = tuple(payload[i:i + 8])
                    have[k] += 1
                    who.setdefault(k, f"{kp.name} {display_path(path, kp.result.programs)}")
    return have, who


def _blocks_at_end(net, plc_name):
    """[(path, type, {output: shown value})] of the MIP blocks of one PLC at the end."""
    out = []
    for plc, path, typ, diag, vals, _ in observer(net).at(None):
        if plc != plc_name:
            continue
        shown = {n: (enum_name(t, v) if t.upper().startswith("E_") else v)
                 for (n, t), v in zip(diag, vals)}
        out.append((path, typ, shown))
    return out


def _carried_up(net, station, last_s=10):
    """(telegrams up from `station` carrying a block in the last `last_s` virtual seconds, how
    many of them the radio delivered), or None without a trace."""
    if net.trace_path is None or not net.trace_path.is_file():
        return None
    net.flush_trace()
    sent = arrived = 0
    for line in _window_lines(net.trace_path, max(0, net.now - last_s * SEC), net.now):
        if '"ev":"radio"' not in line:
            continue
        d = json.loads(line)
        if d.get("st") == station and d.get("dir") != "down" and d.get("regs", 0) >= 1:
            sent += 1
            arrived += not d.get("lost")
    return sent, arrived


def _describe(e, origin_ms):
    ms = e[4] << 48 | e[5] << 32 | e[6] << 16 | e[7]
    return f"address {e[1]} value {e[3]} ({(ms - origin_ms) / 1000:.3f} s)"


def _list(events, origin_ms, most=3):
    shown = ", ".join(_describe(e, origin_ms) for e in events[:most])
    return shown + (f" and {len(events) - most} more" if len(events) > most else "")


def chain_fault(net):
    """A ChainFault naming the events that did not reach the control system once and the hop
    where they stopped, or None (no relay and control system, or nothing missing or doubled)."""
    relays, fars = _ends(net)
    if not relays or not fars:
        return None
    relay, far = relays[0], fars[0]
    want = relay.expected()
    missing = relay.missing(far)
    dups = []
    drivers = list(far.drivers) if hasattr(far, "drivers") else [None]
    for d in drivers:
        dups += far.duplicates(d) if d else far.duplicates()
    if not missing and not dups:
        return None
    origin = relay.origin_ms
    have, who = _delivered(net)
    st = relay.stats()
    taken = st["acknowledged"]             # the relay lets its entries go in order
    index = {tuple(e): i for i, e in enumerate(want)}
    t_of = lambda e: (((e[4] << 48 | e[5] << 32 | e[6] << 16 | e[7]) - origin) * 1_000_000)  # noqa: E731
    station = relay.plc.at if isinstance(relay.plc.at, int) else 1
    if missing:
        first = missing[0]
        at_relay = [e for e in missing if index.get(tuple(e), 0) >= taken]
        delivered = [e for e in missing if have[tuple(e)] and e not in at_relay]
        rest = [e for e in missing if e not in at_relay and e not in delivered]
        n, total = len(missing), len(want)
        head = f"{n} of {total} events of {relay.name} did not reach {far.name}"
        groups = {"relay": at_relay, "hand-over": delivered, "reader": rest}

        def fault(group, text):
            """The line of the first event's group; the other groups' counts after it."""
            where = {"relay": "at the relay", "hand-over": "at the hand-over",
                     "reader": "after the reader"}
            others = [f"{len(v)} {where[k]}" for k, v in groups.items() if k != group and v]
            more = f" (of the others: {', '.join(others)})" if others else ""
            return ChainFault(f"{head}, {text}{more}", t_of(first), station)

        if at_relay and first in at_relay:
            return fault("relay", f"stopped at the relay: {_list(at_relay, origin)}; its reader "
                                  f"never took them ({relay.report().split(': ', 1)[1]})")
        if delivered and first in delivered:
            return fault("hand-over", f"stopped at the hand-over: {_list(delivered, origin)}; "
                                      f"{who[tuple(first)]} (MIP_Receiver) delivered them, "
                                      f"{far.name} never took them")
        # the reader took them (the relay let them go) and no receiver delivered them
        senders = [(p, sh) for p, typ, sh in _blocks_at_end(net, relay.plc.name)
                   if typ in ("MIP_Sender", "MIP_BufferSender", "MIP_Link")]
        busy = [(p, sh) for p, sh in senders
                if any(str(v) != "MIP_WAIT_NONE" for k, v in sh.items() if k.upper().endswith("WAITREASON"))
                or any(str(v) not in ("MIP_ERR_NONE", "0") for k, v in sh.items()
                       if k.upper().endswith("ERRORID"))]
        if senders and not busy:
            return fault("reader", f"stopped at the logger: {_list(rest, origin)}; the reader took "
                                   f"them from the relay ({taken} acknowledged), but no record the "
                                   "sender carried holds them and the sender ended idle with "
                                   "nothing in flight")
        if busy:
            p, sh = busy[0]
            wait = next((str(v) for k, v in sh.items() if k.upper().endswith("WAITREASON")), "")
            hop = "the radio" if wait in _ON_THE_RADIO else "the sender"
            diag = " ".join(f"{k}={v}" for k, v in sh.items())
            seen = _carried_up(net, station) if hop == "the radio" else None
            if seen and seen[1]:
                # the radio delivered the sender's telegrams: the receiving side did not take them
                rcv = [(q, sq) for pl in net.plcs for q, typ, sq in _blocks_at_end(net, pl)
                       if typ in ("MIP_Receiver", "MIP_Link") and pl != relay.plc.name]
                tail = "".join(f", {q.rsplit('.', 1)[-1]} with " + " ".join(f"{k}={v}" for k, v in sq.items())
                               for q, sq in rcv[:1])
                return fault("reader", f"stopped at the receiver: {_list(rest, origin)}; the reader "
                                       f"took them from the relay, the radio delivered {seen[1]} of "
                                       f"the sender's {seen[0]} telegrams up in the last 10 s, no "
                                       f"receiver delivered them; {p.rsplit('.', 1)[-1]} ended with "
                                       f"{diag}{tail}")
            return fault("reader", f"stopped at {hop}: {_list(rest, origin)}; the reader took them "
                                   f"from the relay, no receiver delivered them, and "
                                   f"{p.rsplit('.', 1)[-1]} ended with {diag}")
        return fault("reader", f"stopped after the reader: {_list(rest, origin)}; the reader took "
                               "them from the relay, no receiver delivered them")
    # doubled at the control system
    d = dups[0]
    key = next((e for e in want if (e[1] == d.get("offset", d.get("address"))
                                    and (e[3] == d["value"] or (e[0] << 16 | e[3]) == d["value"]))),
               None)
    twice = key is not None and have[tuple(key)] > 1
    hop = "the receiver" if twice else "the hand-over"
    why = ("a receiver delivered it twice" if twice else
           "the receivers delivered it once, the hand-over wrote it again")
    what = _describe(key, origin) if key is not None else f"value {d['value']}"
    return ChainFault(f"{len(dups)} events of {relay.name} doubled at {far.name}, at {hop}: "
                      f"{what}, taken again at {d['t_s']:.3f} s; {why}",
                      int(d["t_s"] * SEC), station)
