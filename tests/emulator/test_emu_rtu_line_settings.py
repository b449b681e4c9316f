"""Line settings of the emulator's `--rtu` lines that Modbus RTU cannot have are refused in one
line (issue 38, items 4 and 5): data bits other than 8 (MODBUS over Serial Line Specification
and Implementation Guide V1.02, section 2.5.1: "8 data bits"), baud rates a tty cannot be set to
(before: accepted, the timing used them while a real tty was set to 19,200), and --allow-127
with --rtu (an FC16 of 124..127 registers does not fit the 256 bytes of an RTU frame, same
section; before: accepted, and such a request got silence over RTU)."""
import subprocess

import pytest

from miptest.emu import BINARY, FAST, Emulator


@pytest.mark.parametrize("args,msg", [
    (["--rtu", "pty:19200:7E1=trm1@1"], "frame '7E1': Modbus RTU has 8 data bits"),
    (["--rtu", "pty:9600:7N2=trm1@1"], "frame '7N2': Modbus RTU has 8 data bits"),
    (["--rtu", "pty:12345:8E1=trm1@1"], "baud rate 12345 is not one a serial line can be set to"),
    (["--rtu", "/dev/ttyS0:250000:8E1=trm1@1"], "baud rate 250000 is not one a serial line can be set to"),
    (["--allow-127", "--rtu", "pty=trm1@1"], "--allow-127 with --rtu: an FC16 of more than 123"),
    (["--rtu", "pty=trm1@1", "--allow-127"], "--allow-127 with --rtu: an FC16 of more than 123"),
])
def test_rtu_line_settings_rtu_cannot_have_are_refused_in_one_line(args, msg):
    p = subprocess.run([str(BINARY), *args], capture_output=True, text=True, timeout=10)
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    assert p.stderr.count("\n") == 1 and msg in p.stderr, p.stderr
    assert p.stderr.startswith("mip-emulator: error: "), p.stderr


@pytest.mark.parametrize("spec", ["19200:8E1", "9600:8N2", "115200:8O1", "1000000:8N1", "300:8E1"])
def test_rtu_line_settings_rtu_can_have_are_taken(tmp_path, spec):
    emu = Emulator(*FAST, "--rtu", f"pty:{tmp_path / 'tty'}:{spec}=trm1@1")
    assert emu.stop() == 0


def test_allow_127_without_rtu_is_still_taken():
    emu = Emulator(*FAST, "--allow-127")
    assert emu.stop() == 0
