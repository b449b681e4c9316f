#!/usr/bin/env python3
"""Writes the small seed corpus of the fuzz harness (see fuzz_mipemu.c for the input format)."""
import struct
import sys
from pathlib import Path

out = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).parent / "corpus")
out.mkdir(parents=True, exist_ok=True)


def frame(tid, unit, pdu, proto=0):
    return struct.pack(">HHHB", tid, proto, len(pdu) + 1, unit) + pdu


def feed(ep, data):
    """Operations that feed data to endpoint ep in chunks of at most 255 bytes."""
    ops = b""
    for i in range(0, len(data), 255):
        chunk = data[i:i + 255]
        ops += bytes([ep << 2, len(chunk)]) + chunk
    return ops


def regs(vals):
    return b"".join(struct.pack(">H", v) for v in vals)


rd = lambda fc, a, q: struct.pack(">BHH", fc, a, q)
fc16 = lambda a, v: struct.pack(">BHHB", 16, a, len(v), (2 * len(v)) & 0xFF) + regs(v)
fc23 = lambda ra, rq, wa, v: struct.pack(">BHHHHB", 23, ra, rq, wa, len(v), (2 * len(v)) & 0xFF) + regs(v)
adv = lambda n: bytes([2, n])
nxt = b"\x03"

seeds = {
    "trm_read": b"\x01\x0a" + feed(1, frame(1, 1, rd(3, 2198, 125))),
    "mdp_read_fc4": b"\x01\x0a" + feed(0, frame(1, 2, rd(4, 0, 3))),
    "dyn_uplink": b"\x00\x0a" + feed(1, frame(1, 1, fc16(2001, [1, 2, 3]))) + adv(200) + nxt * 8
    + feed(0, frame(2, 1, rd(3, 198, 5))),
    "dyn_downlink_fc23": b"\x01\x0a" + feed(0, frame(1, 2, fc23(198, 10, 10, [5, 6]))) + adv(255) * 3
    + feed(2, frame(2, 1, rd(3, 2198, 4))),
    "static_fc6": b"\x04\x05" + feed(1, frame(1, 1, struct.pack(">BHH", 6, 2003, 9))) + adv(100)
    + feed(0, frame(2, 1, rd(3, 199, 6))),
    "oversize_127": b"\x08\x0a" + feed(1, frame(1, 1, fc16(2001, list(range(127))))) + adv(50),
    "oversize_default": b"\x00\x0a" + feed(1, frame(1, 1, fc16(2001, list(range(127))))),
    "lossy_burst": b"\x73\x0a" + feed(3, frame(1, 1, fc16(2001, [9] * 40))) + adv(255) * 6
    + feed(0, frame(2, 4, rd(3, 0, 3))),
    "unknown_fc": b"\x00\x0a" + feed(0, frame(1, 1, b"\x01\x00\x00\x00\x01") + frame(2, 1, b"\x2b\x0e\x01\x00")),
    "unknown_unit": b"\x00\x0a" + feed(0, frame(1, 9, rd(3, 0, 1))),
    "malformed_proto": b"\x00\x0a" + feed(0, frame(1, 1, rd(3, 2, 1), proto=5)) + feed(0, frame(2, 1, rd(3, 2, 1))),
    "pipelined": b"\x01\x0a" + feed(0, b"".join(frame(i, 1 + i % 2, rd(3, 2, 1)) for i in range(10))),
    # the SIPROTEC relay (endpoint stations + 1 = 2 here): read, acknowledge, bad writes, reset
    "relay_handshake": b"\x00\x0a" + adv(40) + feed(2, frame(1, 1, rd(3, 600, 26))
                                                   + frame(2, 1, struct.pack(">BHH", 6, 601, 1 | 3 << 8))
                                                   + frame(3, 1, rd(3, 600, 26))
                                                   + frame(4, 1, fc16(601, [2 | 3 << 8]))
                                                   + frame(5, 1, struct.pack(">BHH", 6, 600, 0))
                                                   + frame(6, 1, fc16(600, [1, 2]))
                                                   + frame(7, 1, struct.pack(">BHH", 6, 601, 0x8000))
                                                   + frame(8, 1, rd(4, 600, 2))),
}
for name, data in seeds.items():
    (out / name).write_bytes(data)
print(f"{len(seeds)} seeds in {out}")
