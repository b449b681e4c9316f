"""The processes the demos, the bench and the tests start (soft-PLCs, the emulator, peers): a
free TCP port, waiting until a process listens on its port, stopping (SIGTERM, then SIGKILL
after a bounded wait). One copy for every part: plcharness is the lowest package they all use.
"""
from __future__ import annotations

import signal
import socket
import subprocess
import time
from pathlib import Path


def free_port(host="127.0.0.1") -> int:
    """A TCP port free on host now (the kernel's choice; free until someone else takes it)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def wait_port(port, host="127.0.0.1", timeout=5.0, proc=None, step=0.05) -> bool:
    """True as soon as a TCP connection to host:port succeeds; False after timeout seconds, or
    at once when proc (a Popen) has exited."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            socket.create_connection((host, port), timeout=min(1.0, max(0.05, timeout))).close()
            return True
        except OSError:
            pass
        if (proc is not None and proc.poll() is not None) or time.monotonic() >= deadline:
            return False
        time.sleep(step)


def stop(*procs, timeout=5.0):
    """SIGTERM to every process still running, then each waited for until one shared deadline
    `timeout` seconds on; one still running then gets SIGKILL (and is waited for)."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + timeout
    for p in procs:
        try:
            p.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


class Processes:
    """Named processes, each with its output in a log file; stop() ends them all."""

    def __init__(self):
        self.procs = []             # (name, Popen, log file object, log path)

    def start(self, name, cmd, log, **kw):
        """cmd started in its own session, stdin from /dev/null, stderr (and stdout unless
        given) into the file log."""
        f = open(log, "w")
        p = subprocess.Popen(cmd, stdout=kw.pop("stdout", f), stderr=f,
                             stdin=subprocess.DEVNULL, start_new_session=True, **kw)
        self.procs.append((name, p, f, log))
        return p

    def exited(self):
        """(name, exit code, the last 3 lines of its log) of the first process that has
        exited, else None."""
        for name, p, _, log in self.procs:
            if p.poll() is not None:
                return name, p.returncode, Path(log).read_text().strip().splitlines()[-3:]
        return None

    def stop(self, timeout=5.0):
        stop(*(p for _, p, _, _ in self.procs), timeout=timeout)
        for _, _, f, _ in self.procs:
            f.close()
        self.procs = []


class NotReady(RuntimeError):
    """A server that exited or said nothing matching its ready line in time (one line)."""


class Server:
    """A server process: started with its output in pipes, ready once a line on its stdout
    matches `ready` (a regex; match: that match, first: the line) within timeout seconds, else
    stopped and NotReady with the last line of its stderr. stop(): SIGTERM, SIGKILL after `timeout`; the exit
    code."""

    def __init__(self, cmd, ready=r"listening", timeout=30, **popen):
        import re
        import select
        self.proc = subprocess.Popen([str(c) for c in cmd], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, **popen)
        t_end = time.monotonic() + timeout
        self.first, self.match = "", None
        while time.monotonic() < t_end:
            # a line without blocking past the deadline (a hung server is an error)
            if not select.select([self.proc.stdout], [], [], max(0.0, t_end - time.monotonic()))[0]:
                break
            line = self.proc.stdout.readline()
            if not line:                    # its stdout closed: it is exiting, say why
                try:
                    self.proc.wait(timeout=max(0.1, min(2.0, t_end - time.monotonic())))
                except subprocess.TimeoutExpired:
                    pass
                break
            self.match = re.search(ready, line)
            if self.match:
                self.first = line.strip()
                return
        err = self.proc.stderr.read().strip() if self.proc.poll() is not None else ""
        self.stop()
        last = err.splitlines()[-1] if err else "no ready line"       # one line: its last word
        raise NotReady(f"{Path(str(cmd[0])).name} did not start: {last}")

    def stop(self, timeout=10.0):
        if self.proc.returncode is None:
            stop(self.proc, timeout=timeout)
        for f in (self.proc.stdout, self.proc.stderr):
            if f:
                f.close()
        return self.proc.returncode

    def alive(self):
        return self.proc.poll() is None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
