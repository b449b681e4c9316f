"""Crafted Modbus/TCP captures: a classic pcap file (Ethernet, IPv4, TCP) written with struct.

For what no well-behaved client sends (a record counter that goes backwards, an acknowledgement
of a record never sent) and for bytes the dissector must leave alone. One TCP connection per
server port, each frame one whole Modbus/TCP ADU with consistent sequence numbers, so
Wireshark's Modbus/TCP dissector takes each frame as one PDU.
"""
from __future__ import annotations

import struct
from pathlib import Path

from mipkit.capture import tcp_frame as _frame   # the kit's capture builds the same frames

CLIENT = 40000          # first client port; each server port gets its own connection


class Capture:
    """Modbus/TCP exchanges, written as a pcap file by save()."""

    def __init__(self):
        self.frames: list[bytes] = []
        self.conns: dict[int, list] = {}       # server port -> [client port, c seq, s seq, tid]

    def _conn(self, port):
        if port not in self.conns:
            self.conns[port] = [CLIENT + len(self.conns), 1000, 5000, 0]
        return self.conns[port]

    def reconnect(self, port):
        """The next exchange with port goes over a new TCP connection (a new client port)."""
        self.conns.pop(port, None)
        self.conns[port] = [CLIENT + 100 + len(self.frames), 1000, 5000, 0]

    def exchange(self, port, unit, request_pdu: bytes, response_pdu: bytes | None):
        """One request (and its response, unless None): frame numbers of both."""
        c = self._conn(port)
        c[3] += 1
        req = struct.pack("!HHHB", c[3], 0, len(request_pdu) + 1, unit) + request_pdu
        self.frames.append(_frame(c[0], port, c[1], c[2], req))
        c[1] += len(req)
        numbers = [len(self.frames)]
        if response_pdu is not None:
            resp = struct.pack("!HHHB", c[3], 0, len(response_pdu) + 1, unit) + response_pdu
            self.frames.append(_frame(port, c[0], c[2], c[1], resp))
            c[2] += len(resp)
            numbers.append(len(self.frames))
        return numbers

    def write(self, port, unit, addr, values, fc=16):
        """FC16 (or FC23 with a read of one register at addr) of values at addr."""
        data = struct.pack(f"!{len(values)}H", *values)
        if fc == 16:
            req = struct.pack("!BHHB", 16, addr, len(values), 2 * len(values)) + data
            return self.exchange(port, unit, req, struct.pack("!BHH", 16, addr, len(values)))
        req = struct.pack("!BHHHHB", 23, addr, 1, addr, len(values), 2 * len(values)) + data
        return self.exchange(port, unit, req, struct.pack("!BBH", 23, 2, values[0]))

    def read(self, port, unit, addr, values, fc=3):
        """FC3 (or FC4) of len(values) registers at addr, answered with values."""
        req = struct.pack("!BHH", fc, addr, len(values))
        resp = struct.pack(f"!BB{len(values)}H", fc, 2 * len(values), *values)
        return self.exchange(port, unit, req, resp)

    def raw(self, port, unit, request_pdu: bytes, response_pdu: bytes | None = None):
        return self.exchange(port, unit, request_pdu, response_pdu)

    def save(self, path: Path):
        out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)]
        for i, f in enumerate(self.frames):
            out.append(struct.pack("<IIII", 1_700_000_000 + i, 0, len(f), len(f)) + f)
        Path(path).write_bytes(b"".join(out))
        return path
