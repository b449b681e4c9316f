"""The independent relay's command (python -m mippeer.siprotec): it serves, and errors are one line."""
import re
import subprocess
import sys

from pymodbus.client import ModbusTcpClient


def test_serves_the_scripted_events(tmp_path):
    script = tmp_path / "e.txt"
    script.write_text("0 0x0101 5 0x0101 1  # one event at time 0\n")
    p = subprocess.Popen([sys.executable, "-m", "mippeer.siprotec", "--port", "0", "--script", str(script),
                          "--origin", "1000"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        m = re.match(r"mip-peer-relay: listening port=(\d+)", p.stdout.readline())
        assert m
        c = ModbusTcpClient("127.0.0.1", port=int(m.group(1)), timeout=5, retries=0)
        assert c.connect()
        r = c.read_holding_registers(600, count=10)
        assert r.registers == [1, 1 | 1 << 8, 0x0101, 5, 0x0101, 1, 0, 0, 0, 1000]
        assert not c.write_register(601, 1 | 1 << 8).isError()
        assert c.read_holding_registers(600, count=2).registers == [0, 1]
        c.close()
    finally:
        p.terminate()
        p.wait(timeout=10)
        p.stdout.close()
        p.stderr.close()


def test_bad_script_is_one_line(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("0 1 2 3\n")
    p = subprocess.run([sys.executable, "-m", "mippeer.siprotec", "--port", "0", "--script", str(bad)],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode == 2
    assert p.stderr.strip() == f"mip-peer-relay: error: {bad}:1: expected SECONDS W0 W1 W2 W3"
