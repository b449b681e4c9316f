"""Stock OpenPLC v3 holds at most 400 Modbus registers per direction (MAX_MB_IO) and does not
check it: the generator and plc/openplc_limits.py refuse a configuration over it in one line
(a central of 4 stations x 125 registers), and accept the committed ones and 3 stations."""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
GEN = REPO / "plc" / "gen_programs.py"
CHECK = REPO / "plc" / "openplc_limits.py"
from mipprograms import gen


def run(*args):
    return subprocess.run([sys.executable, *map(str, args)], capture_output=True, text=True,
                          cwd=REPO, timeout=120)


def test_committed_openplc_configs_are_within_the_limit_and_generated():
    r = run(CHECK, *sorted((REPO / "plc" / "openplc").glob("*.cfg")))
    assert (r.returncode, r.stderr) == (0, "")
    for name, text in gen.openplc_configs(gen.OPENPLC_STATIONS):
        assert (REPO / "plc" / name).read_text() == text, \
            f"plc/{name} differs from what plc/gen_programs.py writes: run it and commit"


def test_generator_refuses_a_central_of_4_stations_in_one_line(tmp_path):
    r = run(GEN, "--openplc-stations", "4", "-o", tmp_path)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "central-mbconfig.cfg" in r.stderr
    assert "500 registers read (125 + 125 + 125 + 125" in r.stderr
    assert "at most 400" in r.stderr and "at most 3 stations" in r.stderr
    assert list(tmp_path.iterdir()) == []          # nothing written


def test_generator_writes_a_central_of_3_stations(tmp_path):
    r = run(GEN, "--openplc-stations", "3", "-o", tmp_path)
    assert r.returncode == 0, r.stderr
    cfg = (tmp_path / "openplc" / "central-mbconfig.cfg").read_text()
    assert 'Num_Devices = "3"' in cfg and 'device2.slave_id = "3"' in cfg
    assert run(CHECK, tmp_path / "openplc" / "central-mbconfig.cfg").returncode == 0


def test_checker_refuses_4_x_125_with_file_and_line(tmp_path):
    cfg = tmp_path / "mbconfig.cfg"
    cfg.write_text(gen.mbconfig([(f"mdp{s}", s, 502, 198, 10) for s in range(1, 5)]))
    r = run(CHECK, cfg)
    assert r.returncode == 1
    line = next(i for i, t in enumerate(cfg.read_text().splitlines(), 1)
                if t.startswith("device3.Holding_Registers_Read_Size"))
    assert r.stderr == (f"{cfg}:{line}: error: 500 registers read (125 + 125 + 125 + 125, up to "
                        f"device3.Holding_Registers_Read_Size): stock OpenPLC v3 holds at most 400 "
                        f"registers read over all devices (%IW100..%IW499, MAX_MB_IO) and overruns "
                        f"its buffer beyond\n")


@pytest.mark.parametrize("sizes,ok,what", [
    ({"Holding_Registers_Size": [123, 123, 123, 31]}, True, ""),          # 400 exactly
    ({"Holding_Registers_Size": [123, 123, 123, 32]}, False, "401 registers written"),
    ({"Input_Registers_Size": [200], "Holding_Registers_Read_Size": [201]}, False,
     "401 registers read"),
    ({"Coils_Size": [300, 101]}, False, "401 bits written"),
    ({"Discrete_Inputs_Size": [400]}, True, ""),
])
def test_checker_sums_each_direction_over_devices(tmp_path, sizes, ok, what):
    n = max(len(v) for v in sizes.values())
    lines = [f'Num_Devices = "{n}"']
    for i in range(n):
        lines.append(f'device{i}.name = "d{i}"')
        for k, v in sizes.items():
            if i < len(v):
                lines.append(f'device{i}.{k} = "{v[i]}"')
    cfg = tmp_path / "m.cfg"
    cfg.write_text("\n".join(lines) + "\n")
    r = run(CHECK, cfg)
    assert r.returncode == (0 if ok else 1), r.stderr
    assert (what in r.stderr) if what else r.stderr == ""


def test_checker_bad_file_is_one_line(tmp_path):
    cfg = tmp_path / "m.cfg"
    cfg.write_text('Num_Devices = "1"\ndevice0.Holding_Registers_Size = "lots"\n')
    r = run(CHECK, cfg, tmp_path / "missing.cfg")
    assert r.returncode == 1
    assert r.stderr.splitlines() == [
        f"{cfg}:2: error: device0.Holding_Registers_Size: 'lots' is not a number",
        f"{tmp_path / 'missing.cfg'}: error: No such file or directory"]
