"""A SCADA master for the pull way (issue 35): it takes a SIPROTEC-style event recorder's entries
through the SOE_Control handshake and writes each one to JSON lines, written from the manual's
handshake alone, independent of st_lib and the emulator, so MIP_SoeServer and both relays are
checked against a master we did not derive from them.

The handshake (SIPROTEC 5 Kommunikationsprotokolle, C53000-L1800-C055-2, Ausgabe 06.2016, 5.2.5;
registers from SIPROTEC 4 Modbus bus mapping 7UM62, C53000-L1840-C009-03, 3.4.8; docs/chain.md
has the table): the master reads SOE_Control cyclically - together with the entry count and the
three message blocks, in one read -; a raised sequence number shows new entries; it evaluates
the blocks, then writes back the sequence number it read and the number of entries it
evaluated; until that write the slave leaves the data as they are; after a communication
failure it reads again.

What the manual leaves to the master (our choices, docs/chain.md "The control system, pull"):
- An entry is evaluated = written to the JSON-lines file (flushed) before the acknowledgement,
  with `mono_ns`, the time it was taken on CLOCK_MONOTONIC (time.monotonic_ns()).
- The offer last acknowledged (its sequence number and blocks) is remembered: read again
  unchanged, it is not taken again (its acknowledgement was not processed yet, or its answer was
  lost); the acknowledgement is repeated every `reack` seconds. The file's last offer is read at
  start, so a restarted master does not take it twice either.
- An acknowledgement answered with exception 03 was refused: the next read shows why.
- A transport failure or a bad answer: read again, at most `retries` times in a row.

    python -m mippeer.scada --port 15030 --out entries.jsonl --entries 4
"""
import argparse
import json
import os
import signal
import socket
import struct
import sys
import time

BLOCKS = 3          # at most 3 message blocks in one Modbus message (5.2.4)
BLOCK_REGS = 8      # type/bit, address, cause/type, value, 4 registers time stamp (3.4.8)


class ScadaError(Exception):
    """One line saying what is wrong."""


class ModbusException(ScadaError):
    def __init__(self, fc, code):
        super().__init__(f"exception {code:02d} to function {fc}")
        self.code = code


class Client:
    """Modbus TCP client of its own (function codes 3 and 6), one request at a time."""

    def __init__(self, host, port, unit=1, timeout=1.0, after_send=None):
        self.host, self.port, self.unit, self.timeout = host, port, unit, timeout
        self.after_send = after_send   # called after each request is sent, before its answer is
        self.sock = None               # read: a simulation lets its server answer there (lockstep)
        self.tid = 0

    def close(self):
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def _connect(self):
        if self.sock is None:
            try:
                self.sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
            except OSError as e:
                raise ScadaError(f"{self.host}:{self.port}: {e.strerror or e}") from None

    def _recv(self, n):
        buf = b""
        while len(buf) < n:
            part = self.sock.recv(n - len(buf))
            if not part:
                raise ScadaError(f"{self.host}:{self.port}: connection closed")
            buf += part
        return buf

    def request(self, pdu, answer=True):
        """Sends one request; returns the answer's PDU. answer=False: sends and closes without
        reading the answer (a fault for the tests: the answer is lost)."""
        self._connect()
        self.tid = (self.tid + 1) & 0xFFFF
        adu = struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, self.unit) + pdu
        try:
            self.sock.sendall(adu)
            if self.after_send:
                self.after_send()
            if not answer:
                self.close()
                raise ScadaError(f"{self.host}:{self.port}: answer lost (fault injected)")
            while True:
                tid, proto, length, unit = struct.unpack(">HHHB", self._recv(7))
                if proto != 0 or not 2 <= length <= 254:
                    raise ScadaError(f"{self.host}:{self.port}: not a Modbus TCP answer")
                body = self._recv(length - 1)
                if tid == self.tid:
                    break           # an older answer (to a request that timed out) is dropped
        except (OSError, ScadaError) as e:
            self.close()
            if isinstance(e, ScadaError):
                raise
            raise ScadaError(f"{self.host}:{self.port}: {'timed out' if isinstance(e, socket.timeout) else e}") from None
        if body[0] == pdu[0] | 0x80 and len(body) == 2:
            raise ModbusException(pdu[0], body[1])
        if body[0] != pdu[0]:
            self.close()
            raise ScadaError(f"{self.host}:{self.port}: answer to function {body[0]}, asked {pdu[0]}")
        return body

    def read_holding(self, addr, count):
        body = self.request(struct.pack(">BHH", 3, addr, count))
        if len(body) != 2 + 2 * count or body[1] != 2 * count:
            self.close()
            raise ScadaError(f"{self.host}:{self.port}: read of {count} registers answered with {len(body) - 2} bytes")
        return list(struct.unpack(f">{count}H", body[2:]))

    def write_register(self, addr, value, answer=True):
        body = self.request(struct.pack(">BHH", 6, addr, value), answer=answer)
        if body[1:5] != struct.pack(">HH", addr, value):
            self.close()
            raise ScadaError(f"{self.host}:{self.port}: write answer does not echo the request")


def entry(seq, offer, block):
    """One evaluated message block as a JSON-able dict."""
    ts = block[4] << 48 | block[5] << 32 | block[6] << 16 | block[7]
    return {"offer": offer, "seq": seq, "type_bit": block[0], "address": block[1],
            "cause_type": block[2], "value": block[3], "ts_ms": ts, "regs": list(block)}


class SoeMaster:
    """The master's handshake, one poll at a time (`poll`), on a Client. `sink(entries)` stores the
    entries of one offer before they are acknowledged."""

    def __init__(self, client, base=600, sink=None, reack=1.0, last=None, offers=0):
        self.c, self.base, self.sink, self.reack = client, base, sink, reack
        self.last = last            # (seq, blocks) of the offer last acknowledged
        self.offers = offers        # offers taken (the "offer" field of the entries)
        self.last_ack_at = None
        self.lose_answers = set()   # fault injection: lose the answer of these acks (1, 2, ...)
        self.acks = self.reacks = self.refused = self.bad = 0

    def _ack(self, seq, n, now):
        self.last_ack_at = now
        self.acks += 1
        lose = self.acks in self.lose_answers
        try:
            self.c.write_register(self.base + 1, seq | n << 8, answer=not lose)
        except ModbusException as e:
            if e.code != 3:
                raise
            self.refused += 1      # refused: already processed, or out of step; read again

    def poll(self, now):
        """One read of count, SOE_Control and blocks; evaluates and acknowledges a new offer.
        Returns the entries taken (a list, maybe empty). Raises ScadaError on a failure."""
        regs = self.c.read_holding(self.base, 2 + BLOCKS * BLOCK_REGS)
        count, ctrl = regs[0], regs[1]
        seq, n = ctrl & 0xFF, ctrl >> 8 & 0x3F
        if n == 0:
            return []
        if n > BLOCKS or seq == 0 or count < n:
            self.bad += 1
            raise ScadaError(f"bad SOE_Control {ctrl} (sequence {seq}, {n} blocks) with count {count}: "
                             f"at most {BLOCKS} blocks, a sequence number, at least as many entries as blocks")
        blocks = tuple(tuple(regs[2 + BLOCK_REGS * i: 2 + BLOCK_REGS * (i + 1)]) for i in range(n))
        if (seq, blocks) == self.last:
            # taken already: the acknowledgement was not processed yet or its answer was lost
            if self.last_ack_at is None or now - self.last_ack_at >= self.reack:
                self.reacks += 1
                self._ack(seq, n, now)
            return []
        self.offers += 1
        new = [entry(seq, self.offers, b) for b in blocks]
        if self.sink:
            self.sink(new)
        self.last = (seq, blocks)
        self._ack(seq, n, now)
        return new


def resume(path):
    """(last, offers) from an existing JSON-lines file: the last offer it holds."""
    if not path or not os.path.exists(path):
        return None, 0
    rows = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            if line.strip():
                try:
                    rows.append(json.loads(line))
                except ValueError:
                    raise ScadaError(f"{path}:{n}: not a JSON line") from None
    if not rows:
        return None, 0
    top = rows[-1]["offer"]
    blocks = tuple(tuple(r["regs"]) for r in rows if r["offer"] == top)
    return (rows[-1]["seq"], blocks), top


class _Parser(argparse.ArgumentParser):
    def error(self, message):          # one line, not usage + message
        self.exit(2, f"{self.prog}: error: {message}\n")


class _Stop(Exception):
    pass


def _on_term(*_):
    raise _Stop()


def main(argv=None, prog="mip-peer scada"):
    p = _Parser(prog=prog, description="SCADA master of the SOE_Control handshake: every entry to JSON lines")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True, help="Modbus TCP port of the relay or PLC")
    p.add_argument("--unit", type=int, default=1)
    p.add_argument("--base", type=int, default=600, help="PDU address of the entry count (40601 = 600)")
    p.add_argument("--out", required=True, help="JSON lines, one per entry (appended; its last offer is not taken again)")
    p.add_argument("--entries", type=int, default=0, help="stop after this many entries (0: run until SIGTERM)")
    p.add_argument("--interval", type=float, default=0.1, help="seconds between polls")
    p.add_argument("--timeout", type=float, default=1.0, help="answer timeout, s")
    p.add_argument("--retries", type=int, default=10, help="failed polls in a row before giving up")
    p.add_argument("--reack", type=float, default=1.0, help="repeat an unprocessed acknowledgement after this many s")
    a = p.parse_args(argv)
    if not 0 <= a.base <= 65535 - 25:
        p.error("--base must be 0..65510")
    if a.retries < 1 or a.interval < 0 or a.timeout <= 0:
        p.error("--retries must be >= 1, --interval >= 0, --timeout > 0")
    try:
        last, offers = resume(a.out)
        out = open(a.out, "a")
    except OSError as e:
        print(f"{prog}: error: {a.out}: {e.strerror or e}", file=sys.stderr)
        return 2
    except ScadaError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2

    def sink(entries):
        # when it took them, on CLOCK_MONOTONIC (the clock of mip-emulator's trace, whose
        # origin the trace's first "relay" line gives): the live view draws them at that time
        t = time.monotonic_ns()
        for e in entries:
            out.write(json.dumps({**e, "mono_ns": t}) + "\n")
        out.flush()
        os.fsync(out.fileno())

    master = SoeMaster(Client(a.host, a.port, a.unit, a.timeout), a.base, sink, a.reack, last, offers)
    signal.signal(signal.SIGTERM, _on_term)
    taken = fails = 0
    start = time.monotonic()
    status = 0
    try:
        while not a.entries or taken < a.entries:
            try:
                taken += len(master.poll(time.monotonic() - start))
                fails = 0
            except OSError as e:         # the JSON-lines file (the sink): nothing acknowledged
                print(f"{prog}: error: {a.out}: {e.strerror or e}", file=sys.stderr)
                status = 1
                break
            except ScadaError as e:
                fails += 1
                if fails >= a.retries:
                    print(f"{prog}: error: {e} ({fails} polls in a row failed)", file=sys.stderr)
                    status = 1
                    break
            time.sleep(a.interval)
    except (_Stop, KeyboardInterrupt):
        pass
    finally:
        master.c.close()
        out.close()
    print(f"{prog}: entries={taken} acks={master.acks} reacks={master.reacks} refused={master.refused}",
          flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main(prog="python -m mippeer.scada"))
