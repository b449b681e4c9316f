"""The thin executable: real-time and virtual runs, config errors before anything starts."""
import subprocess

import pytest

from plcharness import build_program
from plcharness.procs import free_port
from miptest.rt import COMPILERS, COUNTER, tcp_device


def config(port) -> str:
    """%QW100 written to holding register 0 of the server whenever it changes."""
    cfg = tcp_device(port)
    cfg.add("write", "count", device="out", start=0, size=1, image="%QW100", policy="change")
    return cfg.text()


def run(exe, *args):
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("compiler", COMPILERS)
@pytest.mark.parametrize("mode", ["real", "virtual"])
def test_program_runs_in_both_modes_and_writes_its_outputs(compiler, mode, server, st_file,
                                                           conf_file, tmp_path):
    res = build_program([st_file(COUNTER)], tmp_path / "out", compiler=compiler)
    cfg = conf_file(config(server.port))
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


@pytest.mark.parametrize("compiler", COMPILERS)
def test_real_time_slave_serves_the_image_until_sigterm(compiler, st_file, tmp_path):
    """The executable in real time with -s: a Modbus client sees the counter (%QW100 =
    holding register 100) grow; SIGTERM ends the run cleanly with the stats line."""
    import signal
    import socket
    import struct
    import time

    res = build_program([st_file(COUNTER)], tmp_path / "out", compiler=compiler)
    port = free_port()
    proc = subprocess.Popen([str(res.executable), "-m", "real", "-s", f"127.0.0.1:{port}"],
                            stderr=subprocess.PIPE, text=True)
    try:
        values = []
        deadline = time.monotonic() + 30  # generous: only a bound on a hang, not a timing check
        while time.monotonic() < deadline and (len(values) < 2 or values[-1] <= values[0]):
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=5) as c:
                    c.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 3, 100, 1))
                    reply = c.recv(64)
                    values.append(struct.unpack(">H", reply[9:11])[0])
            except OSError:
                time.sleep(0.05)
        assert len(values) >= 2 and values[-1] > values[0], values
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "real-time:" in err and "overruns" in err
