"""Starting the real mip-emulator server for a test, and a few raw Modbus TCP helpers.

The raw helpers exist only for what a conformant client cannot send (malformed or oversized
frames, pipelining), and tcp_read, one plain FC3 read for a test that only wants the values
(the RTU tests, which check the TCP side of the same registers); everything else in the tests
goes through pymodbus or mbpoll."""
import os
import socket
import struct
import subprocess
import time
from pathlib import Path

from mipcosim.trace import read_trace
from plcharness.procs import NotReady, Server

ROOT = Path(__file__).resolve().parents[3]   # tests/support/miptest/emu.py -> the repository
BINARY = Path(os.environ.get("MIP_EMULATOR", ROOT / "build" / "emulator" / "mip-emulator"))

# A fast radio so that blocks cross within milliseconds of real time.
FAST = ["--bitrate", "1000000", "--slot-gap-ms", "1"]


def run_cli(*args):
    """mip-emulator ARGS to its exit (options it refuses, --help): the CompletedProcess (text)."""
    return subprocess.run([str(BINARY), *map(str, args)], capture_output=True, text=True, timeout=10)


class Emulator(Server):
    """mip-emulator on free ports (plcharness.procs.Server: up once it says where it listens)."""

    def __init__(self, *args, trace=None, preexec_fn=None):
        if not BINARY.exists():
            raise RuntimeError(f"{BINARY} is missing: run `make` first")
        cmd = [str(BINARY), "--mdp-port", "0", "--trm-base-port", "0", *map(str, args)]
        if trace:
            cmd += ["--trace", str(trace)]
        self.trace_path = trace
        try:
            super().__init__(cmd, r"^mip-emulator: listening mdp=([\d.]+):(\d+) trm=([\d,]+)",
                             timeout=30, preexec_fn=preexec_fn)
        except NotReady as e:
            raise RuntimeError(f"emulator did not start: {e}") from None
        self.host = self.match.group(1)
        self.mdp_port = int(self.match.group(2))
        self.trm_ports = [int(p) for p in self.match.group(3).split(",")]

    def trm_port(self, station):
        return self.trm_ports[station - 1]

    def trace(self):
        return read_trace(self.trace_path)


def wait_until(cond, timeout=20.0):
    """Polls cond() until it is true; the timeout is generous, no speed is asserted."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return bool(cond())


def connect(port, host="127.0.0.1"):
    s = socket.create_connection((host, port), timeout=10)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def tcp_read(port, addr, count, unit=1):
    """Holding registers addr.. (FC3) over a fresh Modbus TCP connection to port."""
    s = connect(port)
    try:
        s.sendall(struct.pack(">HHHBBHH", 7, 0, 6, unit, 3, addr, count))
        data = b""
        while len(data) < 9 + 2 * count:
            chunk = s.recv(1024)
            assert chunk, "connection closed"
            data += chunk
        return list(struct.unpack(f">{count}H", data[9:9 + 2 * count]))
    finally:
        s.close()


def frame(tid, unit, pdu, proto=0, length=None):
    if length is None:
        length = len(pdu) + 1
    return struct.pack(">HHHB", tid, proto, length, unit) + pdu


def recv_exact(s, n):
    buf = b""
    while len(buf) < n:
        chunk = s.recv(n - len(buf))
        if not chunk:
            raise ConnectionError(f"closed after {len(buf)} of {n} bytes")
        buf += chunk
    return buf


def recv_frame(s):
    """Returns (tid, unit, pdu) of one response."""
    head = recv_exact(s, 7)
    tid, proto, length, unit = struct.unpack(">HHHB", head)
    assert proto == 0
    return tid, unit, recv_exact(s, length - 1)


def closed_by_peer(s, timeout=10.0):
    s.settimeout(timeout)
    try:
        return s.recv(1) == b""
    except ConnectionResetError:
        return True
