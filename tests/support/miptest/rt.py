"""Shared helpers of the runtime tests (a uniquely named module: every part has its own tests dir)."""
import subprocess
import sys
from pathlib import Path

import pytest

from plcharness.build import matiec_available
from plcharness.config import Config

REPO = Path(__file__).resolve().parents[3]   # tests/support/miptest/rt.py -> the repository


def stc_works() -> bool:
    stc = Path(sys.executable).parent / "stc"
    if not stc.is_file():
        return False
    probe = subprocess.run([str(stc), "--help"], capture_output=True, text=True)
    return probe.returncode == 0


needs_matiec = pytest.mark.skipif(
    not matiec_available(),
    reason="iec2c not on PATH (set PATH and MATIEC_LIB to run the matiec tests)")




def compiler_param(name):
    """A pytest param for a compiler, skipped with the reason when this machine lacks it."""
    if name == "stc":
        return pytest.param("stc", marks=pytest.mark.skipif(
            not stc_works(), reason="stc (.venv/bin/stc) is not installed: run `make venv`"))
    return pytest.param("matiec", marks=needs_matiec)


COMPILERS = [compiler_param("stc"), compiler_param("matiec")]


def one_task(pou: str, interval: str = "T#10ms") -> str:
    """ST source: the POUs (PROGRAM MAIN ...) and the configuration every runtime test uses, one
    cyclic task running MAIN as instance0."""
    return (pou + "CONFIGURATION Config0\nRESOURCE Res0 ON PLC\n"
            f"TASK task0(INTERVAL := {interval}, PRIORITY := 0);\n"
            "PROGRAM instance0 WITH task0 : MAIN;\nEND_RESOURCE\nEND_CONFIGURATION\n")


# counts its scans in %QW100 (what the executable's tests read over Modbus)
COUNTER = one_task("""
PROGRAM MAIN
VAR count AT %QW100 : WORD; END_VAR
count := UINT_TO_WORD(WORD_TO_UINT(count) + 1);
END_PROGRAM
""")

# the smallest program: one variable, one statement
TINY = one_task("""
PROGRAM MAIN
VAR x : INT; END_VAR
x := x + 1;
END_PROGRAM
""")


def tcp_device(port, name="out", host="127.0.0.1", **keys) -> Config:
    """A plcrt config (plcharness.config) of one Modbus TCP device; add its ranges."""
    cfg = Config()
    cfg.add("device", name, host=host, port=port, **keys)
    return cfg


def trigger_range(cfg, kind, name, device, start, image, bits, status=None, size=1, **keys):
    """A [read NAME] / [write NAME] range on the handshake bits (trigger, done, error)."""
    trigger, done, error = bits
    return cfg.add(kind, name, device=device, start=start, size=size, image=image,
                   policy="trigger", trigger=trigger, done=done, error=error, status=status,
                   **keys)


def rtu_device(tty, unit=5, master=None, name="trm", **keys) -> Config:
    """A plcrt config of one Modbus RTU device at 19200 baud, parity even (the emulator's
    8E1 pty), after a [master] of the keys `master` if given; add its ranges."""
    cfg = Config()
    if master:
        cfg.add("master", **master)
    cfg.add("device", name, serial=tty, baud=19200, parity="even", unit_id=unit, **keys)
    return cfg


def rtu_conf(tty, unit=5, master=None) -> str:
    """The RTU tests' config: device trm with read_write_ranges at 2001 (the TRM's write area),
    timeout 300 ms, its error counter in %IW30."""
    return read_write_ranges("trm", 2001, rtu_device(tty, unit, master, timeout="300ms",
                                                     errors="%IW30"))


def read_range(device: str, start: int, cfg=None) -> str:
    """plcrt's [read rd]: one register at `start` into %IW100, on the handshake xRd %QX1.0 ->
    xRdDone %IX1.0 / xRdErr %IX1.1, status %IW11 (as the test programs that use it declare);
    added to cfg (a Config) if given. The config's text."""
    cfg = cfg or Config()
    trigger_range(cfg, "read", "rd", device, start, "%IW100", ("%QX1.0", "%IX1.0", "%IX1.1"),
                  "%IW11")
    return cfg.text()


def read_write_ranges(device: str, start: int, cfg=None) -> str:
    """read_range and its [write wr]: one register at `start` from %QW41, on the handshake xWr
    %QX1.1 -> xWrDone %IX1.2 / xWrErr %IX1.3, status %IW21."""
    cfg = cfg or Config()
    read_range(device, start, cfg)
    trigger_range(cfg, "write", "wr", device, start, "%QW41", ("%QX1.1", "%IX1.2", "%IX1.3"),
                  "%IW21")
    return cfg.text()


# the handshakes of read_write_ranges: [read rd] on xRd -> xRdDone / xRdErr into wRd, status
# wRdStatus; [write wr] of wData on xWr -> xWrDone / xWrErr, status wWrStatus
TRIGGER = one_task("""
PROGRAM MAIN
VAR
  wData AT %QW41 : WORD;
  xRd AT %QX1.0 : BOOL; xWr AT %QX1.1 : BOOL;
  xRdDone AT %IX1.0 : BOOL; xRdErr AT %IX1.1 : BOOL;
  xWrDone AT %IX1.2 : BOOL; xWrErr AT %IX1.3 : BOOL;
  wRdStatus AT %IW11 : WORD; wWrStatus AT %IW21 : WORD;
  wRd AT %IW100 : WORD;
END_VAR
VAR
  x : INT;
END_VAR
x := x + 1;
END_PROGRAM
""")


def handshake(plc, trig, done, err, scans=50):
    """Raises trig until done or err (at most `scans` scans), lowers it; (done, err)."""
    plc.force(trig, True)
    for _ in range(scans):
        plc.scan()
        if plc[done] or plc[err]:
            break
    res = (plc[done], plc[err])
    plc.force(trig, False)
    plc.scan(2)
    plc.unforce(trig)
    return res


def write_read_back(plc, value):
    """read_write_ranges' [write wr] of value (forced into %QW41), then its [read rd] into
    %IW100: both succeed and the value comes back."""
    plc.force("%QW41", value)
    assert handshake(plc, "%QX1.1", "%IX1.2", "%IX1.3") == (True, False)
    assert handshake(plc, "%QX1.0", "%IX1.0", "%IX1.1") == (True, False)
    assert plc["%IW100"] == value


# a plcrt config of every kind of range, valid (the config tests mangle it)
GOOD = """[master]
polling_period = 100ms
timeout = 1s
[device d]
host = 127.0.0.1
port = 5020
unit_id = 3
errors = %IW90
[read r]
device = d
table = input
start = 0
size = 10
image = %IW100
[write w]
device = d
start = 100
size = 123
image = %QW100
policy = trigger
trigger = %QX10.0
done = %IX10.0
error = %IX10.1
status = %IW60
length = %QW99
"""

TOKENS = ["[", "]", "=", "%", "%IW", "%QX1.", "..", "#", '"', "-1", "99999999999999999999",
          "0x10", "1e9s", " ", "\t", "\n", "ms", "[read", "[device", "policy = trigger",
          "size = 0", "image = %IW1023", "device = d", "\x00", "é", "device0.", "Num_Devices ="]


def mangle(text, rng):
    chars = list(text)
    for _ in range(rng.randint(1, 6)):
        op = rng.randrange(3)
        pos = rng.randrange(len(chars) + 1)
        if op == 0 and chars:
            del chars[pos:pos + rng.randint(1, 8)]
        elif op == 1:
            chars[pos:pos] = list(rng.choice(TOKENS))
        else:
            src = rng.randrange(len(chars) or 1)
            chars[pos:pos] = chars[src:src + rng.randint(1, 20)]
    return "".join(chars)


class ModbusServer:
    """A small Modbus TCP server on 127.0.0.1 (thread per connection) for the master's tests:
    holding and input registers, FC 3/4/6/16, a log of (function, address, count)."""

    def __init__(self, size=1000):
        import socketserver
        import struct
        import threading

        self.holding = [0] * size
        self.input = [0] * size
        self.log = []
        self.duplicate_replies = 0  # the next n replies are sent twice (a stale duplicate)
        self.lock = threading.Lock()
        outer = self

        class Handler(socketserver.BaseRequestHandler):
            def handle(self):
                sock = self.request
                while True:
                    head = _recv_exact(sock, 7)
                    if not head:
                        return
                    tid, pid, length, unit = struct.unpack(">HHHB", head)
                    pdu = _recv_exact(sock, length - 1)
                    if pdu is None:
                        return
                    reply = outer._handle(pdu)
                    adu = struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply
                    with outer.lock:
                        twice = outer.duplicate_replies > 0
                        outer.duplicate_replies -= twice
                    sock.sendall(adu * (2 if twice else 1))

        class Server(socketserver.ThreadingTCPServer):
            allow_reuse_address = True
            daemon_threads = True

        self._server = Server(("127.0.0.1", 0), Handler)
        self.port = self._server.server_address[1]
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.05,),
                                        daemon=True)
        self._thread.start()

    def _handle(self, pdu):
        import struct
        fc = pdu[0]
        with self.lock:
            if fc in (3, 4):
                addr, count = struct.unpack(">HH", pdu[1:5])
                self.log.append((fc, addr, count))
                table = self.holding if fc == 3 else self.input
                if addr + count > len(table):
                    return bytes([fc | 0x80, 2])
                return bytes([fc, 2 * count]) + struct.pack(f">{count}H", *table[addr:addr + count])
            if fc == 16:
                addr, count, nbytes = struct.unpack(">HHB", pdu[1:6])
                self.log.append((fc, addr, count))
                if addr + count > len(self.holding):
                    return bytes([fc | 0x80, 2])
                self.holding[addr:addr + count] = struct.unpack(f">{count}H", pdu[6:6 + 2 * count])
                return pdu[:5]
            if fc == 6:
                addr, value = struct.unpack(">HH", pdu[1:5])
                self.log.append((fc, addr, 1))
                self.holding[addr] = value
                return pdu[:5]
            return bytes([fc | 0x80, 1])

    def count(self, fc):
        with self.lock:
            return sum(1 for e in self.log if e[0] == fc)

    def close(self):
        self._server.shutdown()
        self._server.server_close()


def _recv_exact(sock, n):
    buf = b""
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf
