"""plcharness.procs, the process helper of the demos, the bench and the tests: a free port, waiting
for a port, stopping within a bound, a server ready at the line it prints."""
import socket
import subprocess
import sys
import time

import pytest

from plcharness import procs

# a server on a port given as argv[1]: says where it listens, ignores SIGTERM if argv[2] says so
SERVER = """
import signal, socket, sys, time
if len(sys.argv) > 2:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
s = socket.socket()
s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
time.sleep(0.3)
s.bind(("127.0.0.1", int(sys.argv[1])))
s.listen()
print("listening port=%d" % s.getsockname()[1], flush=True)
while True:
    s.accept()[0].close()
"""


def test_free_port_can_be_bound():
    port = procs.free_port()
    with socket.socket() as s:
        s.bind(("127.0.0.1", port))


def test_wait_port_sees_a_server_come_up_and_stop_ends_it():
    port = procs.free_port()
    p = subprocess.Popen([sys.executable, "-c", SERVER, str(port)], stdout=subprocess.DEVNULL)
    try:
        assert procs.wait_port(port, timeout=10, proc=p)
    finally:
        procs.stop(p, timeout=5)
    assert p.returncode == -15                              # SIGTERM was enough
    assert not procs.wait_port(port, timeout=0.2)           # nobody listens any more


def test_stop_kills_what_ignores_sigterm_within_the_bound():
    port = procs.free_port()
    p = subprocess.Popen([sys.executable, "-c", SERVER, str(port), "ignore"],
                         stdout=subprocess.DEVNULL)
    assert procs.wait_port(port, timeout=10, proc=p)
    t0 = time.monotonic()
    procs.stop(p, timeout=0.5)
    assert p.returncode == -9 and time.monotonic() - t0 < 5


def test_wait_port_gives_up_at_once_when_the_process_exited():
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    t0 = time.monotonic()
    assert not procs.wait_port(procs.free_port(), timeout=30, proc=p)
    assert time.monotonic() - t0 < 5


def test_server_is_ready_at_its_line_and_says_in_one_line_why_not():
    with procs.Server([sys.executable, "-c", SERVER, 0], r"port=(\d+)", timeout=10) as srv:
        assert procs.wait_port(int(srv.match.group(1)), timeout=5)
        assert srv.first.startswith("listening port=") and srv.alive()
    assert not srv.alive()
    with pytest.raises(procs.NotReady, match=r"^python[\d.]* did not start: .*ValueError: boom$"):
        procs.Server([sys.executable, "-c", "raise ValueError('boom')"], timeout=10)
