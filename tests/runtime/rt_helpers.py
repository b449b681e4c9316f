"""Shared helpers of the runtime tests (a uniquely named module: every part has its own tests dir)."""
import subprocess
import sys
from pathlib import Path

import pytest

from plcharness.build import matiec_available

REPO = Path(__file__).resolve().parents[2]


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


def _trigger_range(kind: str, device: str, start: int, image: str, bits: tuple, status: str):
    """One plcrt trigger range of one register: [read rd] or [write wr]."""
    trigger, done, error = bits
    return f"""[{kind}]
device = {device}
start = {start}
size = 1
image = {image}
policy = trigger
trigger = {trigger}
done = {done}
error = {error}
status = {status}
"""


def read_range(device: str, start: int) -> str:
    """plcrt's [read rd]: one register at `start` into %IW100, on the handshake xRd %QX1.0 ->
    xRdDone %IX1.0 / xRdErr %IX1.1, status %IW11 (as the test programs that use it declare)."""
    return _trigger_range("read rd", device, start, "%IW100", ("%QX1.0", "%IX1.0", "%IX1.1"),
                          "%IW11")


def read_write_ranges(device: str, start: int) -> str:
    """read_range and its [write wr]: one register at `start` from %QW41, on the handshake xWr
    %QX1.1 -> xWrDone %IX1.2 / xWrErr %IX1.3, status %IW21."""
    return read_range(device, start) + "\n" + _trigger_range(
        "write wr", device, start, "%QW41", ("%QX1.1", "%IX1.2", "%IX1.3"), "%IW21")


def free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


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
