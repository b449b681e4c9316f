"""A stand-in for WinCC OA's Modbus driver in UNICOS mode, written from the WinCC OA pages alone
(not from st_lib or the emulator), so that a PLC's hand-over is checked against a second
implementation (issue 35, items 4 and 7).

Sources (docs/chain.md, "The control system, push (UNICOS)", has the whole table):
- WinCC OA documentation, Treiber_Modbus/modbus_d_unicos ("UNICOS", versions 3.18, 3.19,
  latest; the project's seed winccoa-unicos-modbus.txt): as a slave the driver tells a UNICOS
  frame from a Modbus frame by its reference number, 16#FFFF by default, settable by a config
  entry; the subfunction code is the first byte of the frame's data: 16#01 binary and analog
  status, 16#12 events, 16#11 32-bit events; a UNICOS frame is at most 253 bytes; an event is
  assigned to a DPE by its event offset; the time stamp is UTC; status tables are 96 words;
  only write requests are used; in a redundant pair the active PLC sends to both drivers.

What the pages do not say is our choice (docs/chain.md marks each "our choice"): the frame is
an FC16 write of N registers at the reference number; register 0 = subfunction (high byte) and
number of events (low byte); an event is [offset, value (1 or 2 registers), time stamp
(3 registers: 10 ms since 1970-01-01 UTC)]; a status frame is [16#0100, offset, words...];
registers of a value of several registers come most significant first unless
`little_endian_register` (after WinCC OA's [mod] littleEndianRegister). A frame that breaks
these rules is answered with exception 03. Not tried against WinCC OA.

    python -m mippeer.unicos --port 15040 --out events.jsonl
    python -m mippeer.unicos --port 15040 --pair 15041 --out events.jsonl
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import signal
import socket
import socketserver
import struct
import sys
import threading
import time
from dataclasses import dataclass

SUB_STATUS, SUB_EVENTS32, SUB_EVENTS16 = 0x01, 0x11, 0x12
MAX_PDU = 253                  # bytes of a UNICOS frame (the page), = the Modbus PDU bound
STATUS_WORDS = 96              # words of a status table (the page)
ILLEGAL_FUNCTION, ILLEGAL_ADDRESS, ILLEGAL_VALUE = 1, 2, 3


@dataclass
class UnicosConfig:
    marker: int = 0xFFFF                 # reference number of a UNICOS frame ([mod] addUnicosMarker)
    little_endian_register: bool = False  # registers of a multi-register value, least significant first


def ticks_to_utc(ticks):
    """10 ms since 1970-01-01 UTC -> ISO 8601 text with milliseconds."""
    t = _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc) + _dt.timedelta(milliseconds=10 * ticks)
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


def _join(words, little):
    """A value of several registers: most significant first unless `little`."""
    v = 0
    for w in (reversed(words) if little else words):
        v = (v << 16) | w
    return v


class UnicosDriver:
    """One driver: decodes the frames a PLC writes and keeps what they carried. `handle(adu)`
    answers one Modbus TCP request (None: no answer); the TCP server below calls it, a
    simulation may call it directly. Faults for tests: `mute` (no answer at all),
    `fail_next(n, code)` (the next n UNICOS frames answered with exception `code`)."""

    def __init__(self, name="A", cfg=None, out=None):
        self.name, self.cfg = name, cfg or UnicosConfig()
        self.out = out                     # path of the JSON lines file, or None
        self.events = []                   # every event, in the order received (dicts)
        self.status = {}                   # (plc, offset) -> the last status words
        self.frames = 0                    # UNICOS frames accepted
        self.refused = 0                   # frames answered with an exception
        self.duplicates = 0                # events seen before: same PLC, offset, value, time stamp
        self._seen = set()
        self.holding = {}                  # plain Modbus holding registers written
        self.mute = False
        self._fail = []                    # exception codes for the next UNICOS frames
        self.lock = threading.Lock()

    def fail_next(self, n, code=4):
        with self.lock:
            self._fail += [code] * n

    # -- Modbus TCP --
    def handle(self, adu: bytes):
        if len(adu) < 8:
            return None
        tid, proto, length, unit = struct.unpack(">HHHB", adu[:7])
        pdu = adu[7:6 + length]
        if proto != 0 or len(pdu) != length - 1 or not pdu:
            return None
        with self.lock:
            if self.mute:
                return None
            resp = self._pdu(unit, pdu)
        return struct.pack(">HHHB", tid, 0, len(resp) + 1, unit) + resp

    def _pdu(self, unit, pdu):
        fc = pdu[0]
        try:
            if fc == 16 and len(pdu) >= 3 and struct.unpack(">H", pdu[1:3])[0] == self.cfg.marker:
                if self._fail:
                    self.refused += 1
                    return bytes([fc | 0x80, self._fail.pop(0)])
                self._unicos(unit, pdu)
                return pdu[:5]
            return self._modbus(pdu)
        except _Refuse as e:
            self.refused += 1
            return bytes([fc | 0x80, e.code])

    def _modbus(self, pdu):
        """Plain Modbus (what is not a UNICOS frame): holding registers 0..65535."""
        fc = pdu[0]
        if fc == 3 and len(pdu) == 5:
            addr, n = struct.unpack(">HH", pdu[1:5])
            if not 1 <= n <= 125:
                raise _Refuse(ILLEGAL_VALUE)
            if addr + n > 65536:
                raise _Refuse(ILLEGAL_ADDRESS)
            regs = [self.holding.get(addr + i, 0) for i in range(n)]
            return struct.pack(f">BB{n}H", 3, 2 * n, *regs)
        if fc == 6 and len(pdu) == 5:
            addr, v = struct.unpack(">HH", pdu[1:5])
            self.holding[addr] = v
            return pdu
        if fc == 16 and len(pdu) >= 6:
            addr, n, nb = struct.unpack(">HHB", pdu[1:6])
            if not 1 <= n <= 123 or nb != 2 * n or len(pdu) != 6 + nb:
                raise _Refuse(ILLEGAL_VALUE)
            if addr + n > 65536:
                raise _Refuse(ILLEGAL_ADDRESS)
            for i, v in enumerate(struct.unpack(f">{n}H", pdu[6:])):
                self.holding[addr + i] = v
            return pdu[:5]
        raise _Refuse(ILLEGAL_FUNCTION)

    def _unicos(self, unit, pdu):
        if len(pdu) > MAX_PDU or len(pdu) < 6:
            raise _Refuse(ILLEGAL_VALUE)
        _, n, nb = struct.unpack(">HHB", pdu[1:6])
        if n < 1 or nb != 2 * n or len(pdu) != 6 + nb:
            raise _Refuse(ILLEGAL_VALUE)
        regs = list(struct.unpack(f">{n}H", pdu[6:]))
        sub, count = regs[0] >> 8, regs[0] & 0xFF
        little = self.cfg.little_endian_register
        lines = []
        if sub == SUB_STATUS:
            if not 2 <= n <= 2 + STATUS_WORDS or count != 0:
                raise _Refuse(ILLEGAL_VALUE)
            self.status[(unit, regs[1])] = regs[2:]
            lines.append({"kind": "status", "driver": self.name, "plc": unit, "offset": regs[1],
                          "words": regs[2:], "frame": self.frames + 1})
        elif sub in (SUB_EVENTS32, SUB_EVENTS16):
            vw = 2 if sub == SUB_EVENTS32 else 1
            ew = 1 + vw + 3
            if count < 1 or n != 1 + count * ew:
                raise _Refuse(ILLEGAL_VALUE)
            for i in range(count):
                e = regs[1 + i * ew: 1 + (i + 1) * ew]
                ticks = _join(e[1 + vw:], little)
                ev = {"kind": "event", "driver": self.name, "plc": unit, "sub": sub,
                      "offset": e[0], "value": _join(e[1:1 + vw], little),
                      "ts_10ms": ticks, "utc": ticks_to_utc(ticks), "frame": self.frames + 1}
                # the same point, value and time stamp again: a repeat (WinCC OA would take it
                # as a new value); marked, so a test or soak can report every duplicate
                key = (unit, sub, ev["offset"], ev["value"], ticks)
                ev["duplicate"] = key in self._seen
                self._seen.add(key)
                lines.append(ev)
        else:
            raise _Refuse(ILLEGAL_VALUE)
        self.frames += 1
        self.events += [x for x in lines if x["kind"] == "event"]
        self.duplicates += sum(1 for x in lines if x.get("duplicate"))
        if self.out:
            # when the frame came, on CLOCK_MONOTONIC (the clock of mip-emulator's trace, whose
            # origin the trace's first "relay" line gives): the live view draws it at that time
            t = time.monotonic_ns()
            with open(self.out, "a") as f:
                for x in lines:
                    f.write(json.dumps({**x, "mono_ns": t}) + "\n")


class _Refuse(Exception):
    def __init__(self, code):
        super().__init__(code)
        self.code = code


class _Handler(socketserver.BaseRequestHandler):
    def handle(self):
        drv = self.server.driver
        self.server.clients.add(self.request)
        try:
            f = self.request.makefile("rb")
            while True:
                head = f.read(6)
                if len(head) < 6:
                    return
                length = struct.unpack(">H", head[4:6])[0]
                if length < 2 or length > 260:
                    return
                rest = f.read(length)
                if len(rest) < length:
                    return
                out = drv.handle(head + rest)
                if out is not None:
                    self.request.sendall(out)
        except OSError:
            return
        finally:
            self.server.clients.discard(self.request)


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True


class DriverServer:
    """A driver on a TCP port that can be taken down (the port closed, the connections cut)
    and brought back on the same port."""

    def __init__(self, driver, port=0, host="127.0.0.1"):
        self.driver, self.host, self.port = driver, host, port
        self._srv = None
        self.up()

    def up(self):
        if self._srv:
            return self
        srv = _Server((self.host, self.port), _Handler)
        srv.driver, srv.clients = self.driver, set()
        self.port = srv.server_address[1]
        threading.Thread(target=srv.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
        self._srv = srv
        return self

    def down(self):
        srv, self._srv = self._srv, None
        if not srv:
            return
        srv.shutdown()
        srv.server_close()
        for c in list(srv.clients):
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    @property
    def is_up(self):
        return self._srv is not None


class DriverPair:
    """A redundant pair: driver A and driver B, each on its own port, one JSON lines file for
    both (each line names its driver)."""

    def __init__(self, cfg=None, out=None, ports=(0, 0)):
        self.a = DriverServer(UnicosDriver("A", cfg, out), ports[0])
        self.b = DriverServer(UnicosDriver("B", cfg, out), ports[1])

    def close(self):
        self.a.down()
        self.b.down()


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="mip-peer-unicos",
                                 description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.error = lambda msg: ap.exit(2, f"mip-peer-unicos: error: {msg}\n")   # one line
    ap.add_argument("--port", type=int, default=15040, help="TCP port of driver A (0: any)")
    ap.add_argument("--pair", type=int, metavar="PORT", default=None,
                    help="run a redundant pair: driver B on this port (0: any)")
    ap.add_argument("--marker", type=lambda s: int(s, 0), default=0xFFFF,
                    help="reference number of a UNICOS frame ([mod] addUnicosMarker), default 0xFFFF")
    ap.add_argument("--little-endian-register", action="store_true",
                    help="values of several registers least significant register first")
    ap.add_argument("--out", help="append every event and status table as a JSON line to this file")
    a = ap.parse_args(argv)
    if not 0 <= a.marker <= 0xFFFF:
        ap.error("--marker must be 0..0xFFFF")
    for p in (a.port, a.pair):
        if p is not None and not 0 <= p <= 65535:
            ap.error("ports are 0..65535")
    return a


def main(argv=None):
    a = parse_args(argv)
    cfg = UnicosConfig(a.marker, a.little_endian_register)
    try:
        if a.out:
            open(a.out, "a").close()
        servers = [DriverServer(UnicosDriver("A", cfg, a.out), a.port)]
        if a.pair is not None:
            servers.append(DriverServer(UnicosDriver("B", cfg, a.out), a.pair))
    except OSError as e:
        print(f"mip-peer-unicos: error: {e}", file=sys.stderr)
        return 2
    # SIGUSR1 / SIGUSR2: take driver A / B down, or bring it back (a test's outage)
    def toggle(i):
        def h(*_):
            if i < len(servers):
                s = servers[i]
                s.down() if s.is_up else s.up()
                print(f"mip-peer-unicos: driver {s.driver.name} {'up' if s.is_up else 'down'}",
                      flush=True)
        return h
    signal.signal(signal.SIGUSR1, toggle(0))
    signal.signal(signal.SIGUSR2, toggle(1))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    # the handlers are in place before a test or supervisor learns the ports
    print("mip-peer-unicos: listening " + " ".join(
        f"{s.driver.name}={s.port}" for s in servers), flush=True)

    try:
        while not stop.wait(0.2):
            pass
    except KeyboardInterrupt:
        pass
    for s in servers:
        s.down()
    print("mip-peer-unicos: done " + " ".join(
        f"{s.driver.name}:frames={s.driver.frames},events={len(s.driver.events)},"
        f"duplicates={s.driver.duplicates},refused={s.driver.refused}" for s in servers), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
