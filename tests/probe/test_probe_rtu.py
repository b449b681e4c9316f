"""mip-probe over Modbus RTU (the emulator's RTU slaves on ptys, one line per modem): a correct
station passes every check, and the line's time is added to tTimeout as docs/serial.md says;
a station the MDP does not have is silent on RTU, and the first line says what that means."""
import re
import subprocess
import sys
from pathlib import Path

from miptest.emu import FAST, Emulator

PROBE = Path(sys.executable).parent / "mip-probe"


def test_rtu_station_passes_and_a_missing_one_is_named(tmp_path):
    e = Emulator(*FAST, "--stations", 1, "--rtu", f"pty:{tmp_path}/mdp:115200=mdp",
                 "--rtu", f"pty:{tmp_path}/trm:115200=trm1@1")
    try:
        # a pty takes only 8N1 from pymodbus (docs/serial.md, parity on a pty)
        r = subprocess.run([str(PROBE), "--mdp", f"rtu:{tmp_path}/mdp:115200:8N1",
                            "--trm", f"1=rtu:{tmp_path}/trm:115200:8N1@1",
                            "--trm", f"2=rtu:{tmp_path}/trm:115200:8N1@2",
                            "--watch", "0.3", "--blocks", "3", "--request-timeout", "0.3"],
                           capture_output=True, text=True, timeout=120)
    finally:
        assert e.stop() == 0
    out = r.stdout
    assert "Traceback" not in out + r.stderr
    assert r.returncode == 1, out + r.stderr
    assert re.search(r"^station 1: ok: every check passed$", out, re.M), out
    m = re.search(r"^station 2: FAIL answers: (.*)$", out, re.M)
    assert m and m.group(1).startswith(f"MDP rtu:{tmp_path}/mdp:115200:8N1: no answer to read "
                                       f"of 1 at 9 within 0.3 s (over RTU the MDP is silent for "
                                       f"a unit id without a station: is station 2 configured "
                                       f"at the MDP?)"), out
    assert "+ 220 ms for the RTU line at 115200 baud 8N1 (docs/serial.md)" in out
