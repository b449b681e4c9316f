"""The time slots a station's blocks were seen to travel in, from outside the modems.

The note (Piciorgros, "SPS-Kopplung über MODBUS/IP im Zeitschlitzfunk") says that the data go
"im Rahmen des Stationspollings" (note §1.1.1: within the MDP's polling of the stations) and that
a written block is marked "zur Übertragung im nächsten Funkzyklus" (note §1.1.2: for the next
radio cycle), but gives no register that shows the slots or the cycle: register 1 of the MDP is a
"Statusregister der MDP-810 für die jeweilige Station" whose bits it does not define (note §3.1).
So the slots are derived from the times the probe sees (our choice, docs/commissioning.md "Time
slots seen"):

- The probe writes each measured block as soon as the previous one was confirmed (the sender's
  bit 4 cleared), and sees it arrive when the receiver's read area shows it. A block travels in
  a slot of its station, so the arrivals of two consecutive blocks are a whole number of the
  station's poll cycles apart (the time from one of its slots to the next).
- The cycle: the median of the gaps between consecutive arrivals that lie within 1.5 times the
  smallest gap (the blocks that took the next slot). A block after the first took the next slot
  when its gap is within the probe's error of the cycle (3 x `resolution`, at least a quarter
  of the cycle); else round(gap / cycle) slots, at least 2: the modem repeated it after a loss
  on air (or repeated the previous block's confirmation), or the probe turned round too late.
  A slot that carries nothing is shorter than one that carries a block (on the emulator's radio
  a lost poll's slot is 2 gaps, a slot with a block up and its acknowledgement 3), so a count
  above 2 may be one low; "later" (the blocks that did not take the next slot) is not.
- The probe sees an arrival at most one read period plus a request late (`resolution`). When
  the blocks did not wait for their slot longer than twice that (the median time from a write
  to its arrival), the radio polls faster than the probe can tell: the cycle is not given.
- What it is: the cycle of the station while it carries blocks one way; a radio that polls
  faster than the probe turns round (from a confirmation seen to the next write) shows a whole
  multiple of its cycle, which is the time a PLC as fast as the probe waits for its next block.
"""
from __future__ import annotations

import statistics

NEAR = 1.5          # gaps within NEAR x the smallest one took the next slot (our choice)
ERROR = 3           # ... and a gap within ERROR x resolution (or a quarter cycle) of the cycle
WAIT_OVER = 2       # the blocks waited for their slot: median wait > WAIT_OVER x resolution


def slots_seen(writes, arrivals, resolution):
    """writes: when each block was written (s, monotonic); arrivals: when it was seen at the
    receiver (s, or None: never); resolution: how late the probe may see an arrival (s).
    Returns a dict for the report (ms, rounded to 0.1), or None without two consecutive
    arrivals."""
    gaps = [b - a for a, b in zip(arrivals, arrivals[1:]) if a is not None and b is not None]
    if not gaps:
        return None
    waits = [a - w for w, a in zip(writes, arrivals) if a is not None]
    resolved = statistics.median(waits) > WAIT_OVER * resolution
    out = {"resolved": resolved, "resolution_ms": round(resolution * 1000, 1),
           "gaps_ms": [round(g * 1000, 1) for g in gaps]}
    if not resolved:
        out.update(cycle_ms=None, per_block=None, later=None)
        return out
    cycle = statistics.median([g for g in gaps if g <= NEAR * min(gaps)])
    margin = max(ERROR * resolution, cycle / 4)
    per = [1 if g <= cycle + margin else max(2, round(g / cycle)) for g in gaps]
    out.update(cycle_ms=round(cycle * 1000, 1), per_block=per, later=sum(k > 1 for k in per))
    return out


def slots_text(s):
    """the round trips line's words for slots_seen's dict"""
    if s is None:
        return "slots: fewer than two blocks arrived"
    if not s["resolved"]:
        return (f"its slots: faster than the probe tells apart (it sees an arrival up to "
                f"{s['resolution_ms']:g} ms late)")
    n = len(s["per_block"])
    return (f"its slot every {s['cycle_ms']:g} ms (of the {n} blocks after the first, "
            f"{n - s['later']} in the next slot, {s['later']} later)")
