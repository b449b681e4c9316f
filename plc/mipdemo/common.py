"""What both real-time demos use (the logger's, mipdemo.logger, and the chain's,
mipdemo.chain): the processes they start, the soft-PLCs' Modbus slaves, the emulator and its
trace, the progress lines and the result line."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from plcharness.procs import Processes, free_port  # noqa: F401 (free_port: the demos')

REPO = Path(__file__).resolve().parents[2]        # the checkout (this package is plc/mipdemo/)

class DemoError(Exception):
    pass


class Slave:
    """Reads and writes a soft-PLC's %MW through its Modbus slave (holding 1024 + n)."""

    def __init__(self, port):
        from pymodbus.client import ModbusTcpClient
        import logging
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
        self.port = port
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=1)

    def connect(self, deadline):
        while time.monotonic() < deadline:
            if self.c.connect():
                return
            time.sleep(0.05)
        raise DemoError(f"the soft-PLC's slave on port {self.port} did not come up")

    def read(self, mw, n):
        out = []
        while n > 0:
            k = min(n, 125)
            rr = self.c.read_holding_registers(1024 + mw, count=k)
            if rr.isError():
                raise DemoError(f"reading %MW{mw} from port {self.port}: {rr}")
            out += rr.registers
            mw, n = mw + k, n - k
        return out

    def write(self, mw, words):
        wr = self.c.write_registers(1024 + mw, list(words))
        if wr.isError():
            raise DemoError(f"writing %MW{mw} on port {self.port}: {wr}")

    def close(self):
        self.c.close()


class Procs(Processes):
    """Every process the demo starts; stop() ends them all (SIGTERM, then SIGKILL)."""

    def check_alive(self):
        gone = self.exited()
        if gone:
            name, code, tail = gone
            raise DemoError(f"{name} exited with {code}: {' | '.join(tail)}")


class TraceStats:
    """Link statistics from the emulator's JSON-lines trace, read as it grows."""

    def __init__(self, path):
        self.path, self.pos, self.buf = path, 0, ""
        self.polls = self.lost = self.telegrams = self.blocks = self.blocks_lost = 0

    def update(self):
        try:
            with open(self.path) as f:
                f.seek(self.pos)
                data = f.read()
                self.pos = f.tell()
        except FileNotFoundError:
            return
        self.buf += data
        *lines, self.buf = self.buf.split("\n")
        for line in lines:
            if '"radio"' not in line:
                continue
            ev = json.loads(line)
            self.telegrams += 1
            self.polls += ev["kind"] == "poll"
            self.lost += ev["lost"]
            if ev["regs"]:
                self.blocks += 1
                self.blocks_lost += ev["lost"]


def bar(done, total, width=30):
    k = int(width * done / total) if total else width
    return "[" + "#" * k + "." * (width - k) + f"] {done}/{total}"


def fresh_rundir(path) -> Path:
    """The run's directory, emptied of the files of an earlier run."""
    rundir = Path(path)
    rundir.mkdir(parents=True, exist_ok=True)
    for f in rundir.glob("*"):
        if not f.is_dir():
            f.unlink()
    return rundir


def start_emulator(procs, rundir, args):
    """Starts mip-emulator with `args` (a trace, fault and port options) and returns its
    'listening' line and that line's fields (mdp=, trm=, relay=, ...)."""
    emu = REPO / "build" / "emulator" / "mip-emulator"
    if not emu.is_file():
        raise DemoError(f"{emu} missing: run make")
    p = procs.start("mip-emulator", [str(emu)] + args, rundir / "emulator.log",
                    stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline().strip()
    if not line.startswith("mip-emulator: listening"):
        procs.check_alive()
        raise DemoError(f"mip-emulator did not start: {line!r}")
    return line, dict(kv.split("=", 1) for kv in line.split()[2:])


def modem_port_args(fixed):
    """The emulator's ports: free ones (two demos side by side), or with --fixed-ports its
    defaults, 15020 and 15021.. (emulator/README.md), which a capture can filter on."""
    return [] if fixed else ["--mdp-port", "0", "--trm-base-port", "0"]


def radio_args(realistic):
    """The emulator's radio: the realistic one (9600 bit/s, 20 ms gaps) or a fast one."""
    return (["--bitrate", "9600", "--slot-gap-ms", "20"] if realistic
            else ["--bitrate", "1000000", "--slot-gap-ms", "1"])


class Progress:
    """The demo's two progress lines: redrawn in place on a terminal, else printed once a
    second and at the end."""

    def __init__(self):
        self.tty = sys.stdout.isatty()
        self.last_print = 0.0
        self.t_run = time.monotonic()

    def elapsed(self):
        return time.monotonic() - self.t_run

    def show(self, line1, line2, final=False):
        now = time.monotonic()
        if self.tty:
            sys.stdout.write(f"\r\033[K{line1}\n\033[K{line2}\033[F")
            sys.stdout.flush()
        elif now - self.last_print >= 1 or final:
            print(f"{line1}  {line2}", flush=True)
            self.last_print = now

    def close(self):
        """Leaves the two lines (on a terminal the cursor stood on the first)."""
        if self.tty:
            print("\n")

    def follow(self, poll, limit):
        """The demos' wait: every 0.1 s shows the lines of `poll()` -> (line1, line2, done,
        so_far) until done; after `limit` s a DemoError saying `so_far` (how far it got)."""
        while True:
            line1, line2, done, so_far = poll()
            self.show(line1, line2, final=done)
            if done:
                break
            if self.elapsed() > limit:
                self.close()
                raise DemoError(f"timeout after {limit:.0f} s: {so_far}")
            time.sleep(0.1)
        self.close()


def run_or_fail(run, a):
    """A demo's run(a) -> (problems, figures); None after printing `result: FAIL` for a
    DemoError or an interruption. Ctrl-C and SIGTERM end the run through its finally clauses
    (every process stopped)."""
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    signal.signal(signal.SIGINT, signal.default_int_handler)   # also when started in background
    try:
        return run(a)
    except KeyboardInterrupt:
        print("\nresult: FAIL interrupted")
    except DemoError as e:
        print(f"\nresult: FAIL {e}")
    return None


def result(outcome, ok_line, note=None):
    """A demo's last lines from run_or_fail's outcome (None: its FAIL line is out): note(figures)
    if given, then `result: FAIL <problems>` (exit status 1) or ok_line(figures) (0)."""
    if outcome is None:
        return 1
    problems, r = outcome
    if note:
        print(note(r))
    if problems:
        print("result: FAIL " + "; ".join(problems))
        return 1
    print(ok_line(r))
    return 0
