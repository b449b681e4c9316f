"""Parity on the emulator's ptys (issue 38, item 2). A pty carries bytes, not bits: Linux keeps no
PARENB on a pty (the driver clears it on every tcsetattr), and glibc's tcsetattr reports EINVAL
when the only change a client asked for is one the pty dropped. So an 8E1 client (pyserial,
pymodbus) could open the emulator's pty once and failed on the next open, when the pty still had
the first client's settings. These tests open it as such clients do, several times in a row, and
read the one line the emulator writes at start to say that a pty carries no parity."""
import signal
import subprocess
import time

import pytest

from miptest.emu import BINARY
from miptest.rtu import check_frame, fc3, frame

serial = pytest.importorskip("serial", reason="pyserial is pinned in requirements.txt")


class RtuOnly:
    """mip-emulator serving RTU only, its stderr kept for the test"""

    def __init__(self, spec):
        self.proc = subprocess.Popen([str(BINARY), "--no-tcp", "--rtu", spec],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        assert " rtu=" in line, (line, self.proc.stderr.read() if self.proc.poll() is not None else "")
        self.path = line.strip().split(" rtu=")[1]

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        out, err = self.proc.communicate(timeout=10)
        assert self.proc.returncode == 0, err
        return err


def pyserial_transact(path, parity, unit=1):
    with serial.Serial(path, 19200, parity=parity, timeout=1.0) as s:
        s.write(frame(unit, fc3(2000, 1)))
        return s.read(7)


@pytest.mark.parametrize("parity", [serial.PARITY_EVEN, serial.PARITY_ODD, serial.PARITY_NONE])
def test_an_8e1_8o1_8n1_client_opens_the_pty_again_and_again(parity):
    emu = RtuOnly("pty:19200:8E1=trm1@1")
    try:
        for attempt in range(4):
            rsp = pyserial_transact(emu.path, parity)
            assert check_frame(rsp) == (1, bytes([3, 2, 0, 0])), f"open {attempt + 1}: {rsp.hex()}"
    finally:
        emu.stop()


def test_an_8e1_client_opens_and_closes_without_a_request_then_opens_again():
    """no traffic between the opens: the emulator learns of the close itself (inotify) and
    re-arms the pty then. An open within the emulator's reaction time (well under 1 ms on an idle
    machine) may still come first: the pause stands for a client's restart."""
    emu = RtuOnly("pty:19200:8E1=trm1@1")
    try:
        for attempt in range(3):
            serial.Serial(emu.path, 19200, parity=serial.PARITY_EVEN).close()
            time.sleep(0.1)
        rsp = pyserial_transact(emu.path, serial.PARITY_EVEN)
        assert check_frame(rsp)[0] == 1
    finally:
        emu.stop()


def test_pymodbus_connects_with_parity_none_to_an_8e1_pty_again_and_again():
    """pymodbus sets the port twice in connect() (the second time for its inter-byte timeout):
    with parity E or O that second setting changes nothing a pty keeps, and glibc fails it,
    whatever the emulator does (docs/serial.md, "Parity on a pty"). On a pty the client's parity
    does not matter, so parity N is the setting that works; the line is still timed as 8E1."""
    from pymodbus.client import ModbusSerialClient
    emu = RtuOnly("pty:19200:8E1=trm1@1")
    try:
        for attempt in range(3):
            c = ModbusSerialClient(emu.path, baudrate=19200, parity="N", timeout=1, retries=0)
            assert c.connect(), f"connect() {attempt + 1} returned False"
            r = c.read_holding_registers(2000, count=1, device_id=1)
            assert not r.isError() and r.registers == [0]
            c.close()
    finally:
        emu.stop()


@pytest.mark.parametrize("frame_fmt,says", [("8E1", "even"), ("8O1", "odd"), ("8N1", None)])
def test_the_emulator_says_once_at_start_that_a_pty_carries_no_parity(frame_fmt, says):
    emu = RtuOnly(f"pty:19200:{frame_fmt}=trm1@1")
    path = emu.path
    pyserial_transact(path, serial.PARITY_EVEN)
    err = emu.stop()
    lines = err.splitlines()
    notes = [ln for ln in lines if "parity" in ln]
    assert len(notes) == 1, err
    assert notes[0].startswith(f"mip-emulator: note: {path} is a pty: ")
    assert "no parity" in notes[0] and "not checked" in notes[0]
    if says:
        assert f"{frame_fmt} ({says} parity)" in notes[0]


@pytest.mark.parametrize("frame_fmt,inpck", [("8E1", True), ("8O1", True), ("8N2", False)])
def test_on_a_tty_the_emulator_checks_the_parity_it_is_given(frame_fmt, inpck):
    """A tty path (here a pty the test made, which keeps the input flags): with parity the
    emulator turns input parity checking on (INPCK, neither IGNPAR nor PARMRK: a character with
    a parity error reads as \\0 and its frame fails the CRC); without, off. The stop bits stay."""
    import os
    import termios
    master, slave = os.openpty()
    path = os.ttyname(slave)
    try:
        emu = RtuOnly(f"{path}:19200:{frame_fmt}=trm1@1")
        try:
            iflag, _, cflag, *_ = termios.tcgetattr(slave)
            assert bool(iflag & termios.INPCK) == inpck
            assert not iflag & (termios.IGNPAR | termios.PARMRK)
            assert bool(cflag & termios.CSTOPB) == (frame_fmt[2] == "2")
        finally:
            err = emu.stop()
        assert "parity" not in err        # a tty: no note about ptys
    finally:
        os.close(slave)
        os.close(master)


def test_a_libmodbus_client_killed_with_sigkill_is_followed_by_one_that_opens():
    """libmodbus (plcrt, mbpoll) puts the line's old settings back when it closes it; a client
    killed with SIGKILL cannot, and left the pty raw with 8E1 asked for: the next libmodbus
    client's setup then changed nothing but the parity and failed, 'Invalid argument' (issue
    38, item 1, as seen from the emulator). The emulator re-arms the pty when the killed
    client's descriptor is closed."""
    import shutil
    mbpoll = shutil.which("mbpoll")
    if mbpoll is None:
        pytest.skip("mbpoll is not installed (Debian package mbpoll)")
    emu = RtuOnly("pty:19200:8E1=trm1@1")
    cmd = [mbpoll, "-m", "rtu", "-b", "19200", "-P", "even", "-a", "1", "-r", "2000", "-0",
           "-t", "4", emu.path]
    try:
        for attempt in range(3):
            poller = subprocess.Popen(["stdbuf", "-oL"] + cmd + ["-l", "20"], stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, text=True)
            try:
                for line in poller.stdout:            # polling: the line is set up and in use
                    if line.startswith("[2000]"):
                        break
                else:
                    pytest.fail(f"mbpoll {attempt + 1} did not poll")
            finally:
                poller.kill()                         # SIGKILL: no chance to restore the line
                poller.wait()
                poller.stdout.close()
            time.sleep(0.1)
            r = subprocess.run(cmd + ["-1"], capture_output=True, text=True, timeout=20)
            assert r.returncode == 0 and "[2000]:" in r.stdout, (attempt + 1, r.stdout, r.stderr)
    finally:
        emu.stop()
