"""The SIPROTEC event recorder of mip-emulator (--relay) for tests, and a Modbus master doing the
SOE_Control handshake through pymodbus. Facts and our choices: docs/chain.md, "The relay"."""
import time

from plcharness.procs import NotReady, Server
from pymodbus.client import ModbusTcpClient

from miptest.emu import BINARY

BASE = 600                  # PDU address of register 40601 (our default base)
ORIGIN_MS = 1767225600000   # 2026-01-01T00:00:00Z: the time stamp of the relay's time 0


def write_script(path, events):
    """events: (seconds, w0, w1, w2, w3) tuples -> the --relay script file."""
    path.write_text("".join(f"{t} {a} {b} {c} {d}\n" for t, a, b, c, d in events))
    return path


class RelayServer(Server):
    def __init__(self, opts="", args=()):
        spec = "0:origin=%d" % ORIGIN_MS + ("," + opts if opts else "")
        cmd = [str(BINARY), "--mdp-port", "0", "--trm-base-port", "0", "--relay", spec, *args]
        try:
            super().__init__(cmd, r" relay=(\d+)$", timeout=30)
        except NotReady as e:
            raise RuntimeError(f"relay did not start: {e}") from None
        self.port = int(self.match.group(1))
        self.started = time.monotonic()   # the relay's time 0 is a little after this

    def sleep_past(self, seconds, margin=0.3):
        """Waits until the relay's clock is surely past `seconds` (scripted events happened)."""
        time.sleep(max(0.0, self.started + seconds + margin - time.monotonic()))


def exc(r):
    """The exception code of a pymodbus response, 0 if none."""
    return r.exception_code if r.isError() else 0


class Master:
    """The master side of the handshake (SIPROTEC 5 manual 5.2.5): read the count, SOE_Control and
    the blocks in one request, evaluate, acknowledge with the sequence number and the count."""

    def __init__(self, port, base=BASE):
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=5, retries=0)
        assert self.c.connect()
        self.base = base

    def close(self):
        self.c.close()

    def count(self):
        """Register 40601 alone: reading it does not fix the offered blocks."""
        r = self.c.read_holding_registers(self.base, count=1)
        assert not r.isError(), r
        return r.registers[0]

    def read(self):
        """-> (entries, seq, blocks, raw registers); blocks: dicts of the offered entries."""
        r = self.c.read_holding_registers(self.base, count=26)
        assert not r.isError(), r
        v = r.registers
        seq, n = v[1] & 0xFF, (v[1] >> 8) & 0x3F
        blocks = []
        for b in range(n):
            w = v[2 + 8 * b: 10 + 8 * b]
            blocks.append({"type_bit": w[0], "addr": w[1], "cause_type": w[2], "value": w[3],
                           "ts_ms": w[4] << 48 | w[5] << 32 | w[6] << 16 | w[7]})
        return v[0], seq, blocks, v

    def ack(self, seq, n, reset=False):
        return exc(self.c.write_register(self.base + 1, seq | n << 8 | (0x8000 if reset else 0)))

    def drain(self, limit=10000):
        """Reads and acknowledges until nothing is offered; -> every entry taken, in order."""
        got = []
        for _ in range(limit):
            _, seq, blocks, _ = self.read()
            if not blocks:
                return got
            got += blocks
            assert self.ack(seq, len(blocks)) == 0
        raise AssertionError("the relay never ran empty")
