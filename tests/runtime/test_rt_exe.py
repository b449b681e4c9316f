"""The thin executable: real-time and virtual runs, config errors before anything starts."""
import subprocess

import pytest

from plcharness import build_program
from rt_helpers import COMPILERS, ModbusServer

COUNTER = """
PROGRAM MAIN
VAR count AT %QW100 : WORD; END_VAR
count := UINT_TO_WORD(WORD_TO_UINT(count) + 1);
END_PROGRAM
CONFIGURATION Config0
RESOURCE Res0 ON PLC
TASK task0(INTERVAL := T#10ms, PRIORITY := 0);
PROGRAM instance0 WITH task0 : MAIN;
END_RESOURCE
END_CONFIGURATION
"""

CONFIG = """
[device out]
host = 127.0.0.1
port = {port}
[write count]
device = out
start = 0
size = 1
image = %QW100
policy = change
"""


@pytest.fixture
def server():
    srv = ModbusServer()
    yield srv
    srv.close()


def run(exe, *args):
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("compiler", COMPILERS)
@pytest.mark.parametrize("mode", ["real", "virtual"])
def test_program_runs_in_both_modes_and_writes_its_outputs(compiler, mode, server, st_file,
                                                           tmp_path):
    res = build_program([st_file(COUNTER)], tmp_path / "out", compiler=compiler)
    cfg = tmp_path / "plc.conf"
    cfg.write_text(CONFIG.format(port=server.port))
    proc = run(res.executable, "-m", mode, "-n", "20", "-c", str(cfg))
    assert proc.returncode == 0, proc.stderr
    assert "20 scans" in proc.stderr
    # the last scan's output reached the device: the program counted 20 scans
    assert server.holding[0] == 20


@pytest.mark.parametrize("compiler", COMPILERS)
def test_bad_config_stops_before_anything_starts(compiler, st_file, tmp_path):
    res = build_program([st_file(COUNTER)], tmp_path / "out", compiler=compiler)
    cfg = tmp_path / "bad.conf"
    cfg.write_text("[device out]\nhost = 127.0.0.1\n[read r]\ndevice = out\nstart = 0\n"
                   "size = 200\nimage = %IW100\n")
    proc = run(res.executable, "-m", "virtual", "-n", "5", "-c", str(cfg))
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        f"{cfg}:6: error: size: 200 registers in one holding read request (1..125)"]
    assert proc.stdout == ""


@pytest.mark.parametrize("compiler", COMPILERS)
def test_openplc_mbconfig_runs_unchanged(compiler, server, st_file, tmp_path):
    res = build_program([st_file(COUNTER)], tmp_path / "out", compiler=compiler)
    server.holding[3] = 1234
    cfg = tmp_path / "mbconfig.cfg"
    cfg.write_text(f'''Num_Devices = "1"
Polling_Period = "100"
Timeout = "1000"
# ------------
#   DEVICE 0
# ------------
device0.name = "modem"
device0.slave_id = "1"
device0.protocol = "TCP"
device0.address = "127.0.0.1"
device0.IP_Port = "{server.port}"
device0.RTU_Baud_Rate = "115200"
device0.RTU_Parity = "None"
device0.RTU_Data_Bits = "8"
device0.RTU_Stop_Bits = "1"
device0.RTU_TX_Pause = "0"

device0.Discrete_Inputs_Start = "0"
device0.Discrete_Inputs_Size = "0"
device0.Coils_Start = "0"
device0.Coils_Size = "0"
device0.Input_Registers_Start = "0"
device0.Input_Registers_Size = "0"
device0.Holding_Registers_Read_Start = "3"
device0.Holding_Registers_Read_Size = "1"
device0.Holding_Registers_Start = "10"
device0.Holding_Registers_Size = "1"
''')
    proc = run(res.executable, "-m", "virtual", "-n", "50", "-c", str(cfg))
    assert proc.returncode == 0, proc.stderr
    # OpenPLC's behaviour: every polling period (0, 100 ... 400 ms), read and write,
    # unconditionally; at exit the last outputs are written once more
    assert server.count(3) == 5
    assert server.count(16) == 6
    assert server.holding[10] == 50


def test_bad_command_line_is_one_line_exit_2(st_file, tmp_path):
    res = build_program([st_file(COUNTER)], tmp_path / "out", compiler="stc")
    proc = run(res.executable, "-m", "fast")
    assert proc.returncode == 2
    assert proc.stderr.strip().endswith("error: -m takes real or virtual")
    proc = run(res.executable, "-c", str(tmp_path / "missing.conf"))
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "cannot open" in proc.stderr
