"""The SOE relay's scripted events and the entries a logger must store from them: the data of
the SOE reader's tests in tests/st_lib (soe_bench: the block on its own) and tests/chain
(test_chain_soe: the block in a chain with the relay)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Entry:
    """One SOE entry as the logger stores it: the relay's four words and its time stamp."""
    type_bit: int
    address: int
    cause_type: int
    value: int
    time_ms: int


def script(n, start_s=0.05, every_s=0.013, seed=0):
    """n events at distinct times: (t_s, [type/bit, address, cause/type, value])."""
    out = []
    for k in range(n):
        out.append((start_s + k * every_s,
                    [0x0100 + (k * 7 + seed) % 16, 100 + (k * 13 + seed) % 900, 0x0101 + (k % 3),
                     (k * 31 + seed) & 0xFFFF]))
    return out


def expected(events, origin_ms=1767225600000):
    return [Entry(*w, origin_ms + int(round(t * 1e9)) // 1000000) for t, w in events]
