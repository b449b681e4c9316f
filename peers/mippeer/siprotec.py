"""A SIPROTEC event recorder (Ereignisschreiber) as a Modbus TCP slave, written from the manuals'
text alone, not from the emulator's C code, so that a master's handshake is checked against a
second implementation (issue 35, item 7).

Sources (docs/chain.md, "The relay", has the whole table):
- SIPROTEC 5 Kommunikationsprotokolle, C53000-L1800-C055-2, Ausgabe 06.2016, section 5.2
  (Ereignisfolge; 5.2.4 Meldeblöcke, 5.2.5 Handshake-Mechanismus): SOE_Control with the
  sequence number (Ablaufnummer) and the number of message blocks; bit 14 "Start GS" always 0;
  bit 15 "Liste zurücksetzen" clears the recorder, sent with an acknowledgement or written with
  sequence number 0, the sequence number is not reset; at most 3 message blocks per message;
  the master acknowledges by writing back the sequence number read and the number of entries it
  evaluated; the slave then deletes them and raises the sequence number; until that write the
  data stay as they are, so a repeated read sees the same.
- SIPROTEC 4 Modbus bus mapping 7UM62, C53000-L1840-C009-03, section 3.4.8: 40601 number of
  entries not yet read, 40602 SOE_Control (the only register with write access), 40603-40626
  three message blocks of register type / bit offset, register address, message cause /
  indication type, value and 4 registers of time stamp; a write to the others is rejected with
  exception code 03.

Where the manuals found are silent, the choices of docs/chain.md's table are taken ("our choice":
bit positions of the sequence number and count, the time stamp format, capacity and overflow,
the answer to a wrong acknowledgement, read-only blocks beyond the count read as 0).

    python -m mippeer.siprotec --port 15030 --script events.txt --origin 1767225600000
"""
import argparse
import socketserver
import struct
import sys
import threading
from collections import deque
from dataclasses import dataclass


@dataclass
class RelayConfig:
    base: int = 600               # PDU address of 40601 (4X reference 40601 = offset 600)
    capacity: int = 200
    overflow: str = "drop-oldest"  # or "drop-new"
    seq_bits: int = 8
    bad_ack: str = "exc03"         # or "ignore"
    origin_ms: int = 0             # time stamp of the relay's time 0


class ModbusError(Exception):
    def __init__(self, code):
        super().__init__(code)
        self.code = code


class EventRecorder:
    """The recorder and its Modbus registers; time is given by the caller (seconds)."""

    BLOCKS = 3

    def __init__(self, cfg=None):
        self.cfg = cfg or RelayConfig()
        self.entries = deque()      # (w0, w1, w2, w3, ts_ms), oldest first
        self.pending = []           # scripted (t, words) not yet happened, sorted
        self.seq = 0                # nothing shown yet
        self.offer = []             # the entries in the message-block registers now
        self.offer_read = False     # a master has read them: they stay until acknowledged
        self.now = 0.0
        self.lock = threading.Lock()

    # -- events --
    def add(self, t, words):
        self.pending.append((t, tuple(words)))
        self.pending.sort(key=lambda e: e[0])    # stable: equal times keep their order

    def advance(self, now):
        self.now = max(self.now, now)
        while self.pending and self.pending[0][0] <= self.now:
            t, words = self.pending.pop(0)
            self._record(words, self.cfg.origin_ms + int(round(t * 1e9)) // 1000000)

    def _record(self, words, ts_ms):
        if len(self.entries) >= self.cfg.capacity:
            if self.cfg.overflow == "drop-new" or len(self.offer) >= len(self.entries):
                return
            # drop the oldest entry that is not in the message blocks
            del self.entries[len(self.offer)]
        self.entries.append((*words, ts_ms))
        self._refresh_offer()

    def _next_seq(self):
        top = (1 << self.cfg.seq_bits) - 1
        return 1 if self.seq >= top else self.seq + 1

    def _refresh_offer(self):
        if self.offer_read:
            return
        new = list(self.entries)[: self.BLOCKS]
        if new and not self.offer:
            self.seq = self._next_seq()
        self.offer = new

    # -- registers --
    def registers(self):
        regs = [min(len(self.entries), 0xFFFF), self.seq | len(self.offer) << 8]
        for b in range(self.BLOCKS):
            if b < len(self.offer):
                w0, w1, w2, w3, ts = self.offer[b]
                regs += [w0, w1, w2, w3, ts >> 48 & 0xFFFF, ts >> 32 & 0xFFFF, ts >> 16 & 0xFFFF, ts & 0xFFFF]
            else:
                regs += [0] * 8
        return regs

    def read(self, addr, count):
        off = addr - self.cfg.base
        regs = self.registers()
        if off < 0 or off + count > len(regs):
            raise ModbusError(2)
        if off + count > 1 and self.offer:
            self.offer_read = True
        return regs[off: off + count]

    def write(self, addr, values):
        off = addr - self.cfg.base
        if off < 0 or off + len(values) > 26:
            raise ModbusError(2)
        if off != 1 or len(values) != 1:
            raise ModbusError(3)     # only SOE_Control may be written (7UM62 mapping 3.4.8)
        self._control(values[0])

    def _control(self, v):
        seq, n, reset = v & 0xFF, v >> 8 & 0x3F, bool(v & 0x8000)
        if seq == 0 and n == 0 and reset:
            self._clear()
            return
        ok = (seq != 0 and self.offer and seq == self.seq and n <= len(self.offer))
        if not ok:
            if self.cfg.bad_ack == "exc03":
                raise ModbusError(3)
            return
        for _ in range(n):
            self.entries.popleft()
        if n:
            self.offer, self.offer_read = [], False
        if reset:
            self._clear()
        self._refresh_offer()

    def _clear(self):
        self.entries.clear()
        self.offer, self.offer_read = [], False

    # -- Modbus TCP ADU in, ADU out (None: close the connection) --
    def handle(self, adu):
        if len(adu) < 8:
            return None
        tid, proto, length, unit = struct.unpack(">HHHB", adu[:7])
        if proto != 0 or length != len(adu) - 6:
            return None
        pdu = adu[7:]
        fc = pdu[0]
        try:
            with self.lock:
                out = self._pdu(fc, pdu)
        except ModbusError as e:
            out = bytes([fc | 0x80, e.code])
        return struct.pack(">HHHB", tid, 0, len(out) + 1, unit) + out

    def _pdu(self, fc, pdu):
        if fc == 3:
            if len(pdu) != 5:
                raise ModbusError(3)
            addr, count = struct.unpack(">HH", pdu[1:5])
            if not 1 <= count <= 125:
                raise ModbusError(3)
            regs = self.read(addr, count)
            return bytes([3, 2 * count]) + struct.pack(f">{count}H", *regs)
        if fc == 6:
            if len(pdu) != 5:
                raise ModbusError(3)
            addr, value = struct.unpack(">HH", pdu[1:5])
            self.write(addr, [value])
            return bytes(pdu)
        if fc == 16:
            if len(pdu) < 6:
                raise ModbusError(3)
            addr, count, nbytes = struct.unpack(">HHB", pdu[1:6])
            if not 1 <= count <= 123 or nbytes != 2 * count or len(pdu) != 6 + nbytes:
                raise ModbusError(3)
            self.write(addr, list(struct.unpack(f">{count}H", pdu[6:])))
            return bytes(pdu[:5])
        raise ModbusError(1)


class _Handler(socketserver.BaseRequestHandler):
    def handle(self):
        rec = self.server.recorder
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
            if self.server.clock:
                with rec.lock:
                    rec.advance(self.server.clock())
            out = rec.handle(head + rest)
            if out is None:
                return
            self.request.sendall(out)


class RelayServer(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, recorder, port=0, host="127.0.0.1", clock=None):
        super().__init__((host, port), _Handler)
        self.recorder = recorder
        self.clock = clock    # seconds since the relay's start, or None: time moves only by advance()

    @property
    def port(self):
        return self.server_address[1]

    def start(self):
        threading.Thread(target=self.serve_forever, daemon=True).start()
        return self


def load_script(path):
    events = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            line = line.split("#")[0].split()
            if not line:
                continue
            if len(line) != 5:
                raise ValueError(f"{path}:{n}: expected SECONDS W0 W1 W2 W3")
            words = [int(x, 0) for x in line[1:]]
            if any(not 0 <= w <= 0xFFFF for w in words):
                raise ValueError(f"{path}:{n}: register values are 0..65535")
            events.append((float(line[0]), words))
    return events


def main(argv=None):
    import time
    ap = argparse.ArgumentParser(prog="mip-peer-relay", description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--port", type=int, default=15030)
    ap.add_argument("--script", required=True)
    ap.add_argument("--origin", type=int, default=None, help="ms since 1970 of time 0 (default: now)")
    ap.add_argument("--base", type=int, default=600)
    ap.add_argument("--cap", type=int, default=200)
    ap.add_argument("--overflow", choices=["drop-oldest", "drop-new"], default="drop-oldest")
    ap.add_argument("--bad-ack", choices=["exc03", "ignore"], default="exc03")
    a = ap.parse_args(argv)
    try:
        events = load_script(a.script)
        rec = EventRecorder(RelayConfig(base=a.base, capacity=max(3, a.cap), overflow=a.overflow,
                                        bad_ack=a.bad_ack,
                                        origin_ms=a.origin if a.origin is not None else int(time.time() * 1000)))
        for t, w in events:
            rec.add(t, w)
        t0 = time.monotonic()
        srv = RelayServer(rec, a.port, clock=lambda: time.monotonic() - t0)
    except (OSError, ValueError) as e:
        print(f"mip-peer-relay: error: {e}", file=sys.stderr)
        return 2
    print(f"mip-peer-relay: listening port={srv.port}", flush=True)
    try:
        srv.serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
