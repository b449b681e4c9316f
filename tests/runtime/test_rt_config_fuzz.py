"""The config parser on mangled input: always exit 0 (valid) or 2 with exactly one line
FILE:LINE: error: ..., never a crash."""
import random
import re
import subprocess

import pytest

from plcharness import build_program
from miptest.rt import GOOD, TINY, compiler_param, mangle

MBCONFIG = """Num_Devices = "1"
Polling_Period = "100"
Timeout = "1000"
device0.name = "m"
device0.slave_id = "1"
device0.protocol = "TCP"
device0.address = "127.0.0.1"
device0.IP_Port = "502"
device0.Holding_Registers_Read_Start = "0"
device0.Holding_Registers_Read_Size = "8"
device0.Holding_Registers_Start = "0"
device0.Holding_Registers_Size = "8"
"""


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_mangled_configs_never_crash(compiler, st_file, tmp_path):
    exe = build_program([st_file(TINY)], tmp_path / "out", compiler=compiler).executable
    rng = random.Random(1234)
    cfg = tmp_path / "fuzz.conf"
    outcomes = {0: 0, 2: 0}
    for i in range(150):
        text = mangle(GOOD if i % 2 else MBCONFIG, rng)
        cfg.write_bytes(text.encode("utf-8", "surrogateescape"))
        proc = subprocess.run([str(exe), "--check", "-c", str(cfg)], capture_output=True,
                              timeout=30)
        assert proc.returncode in (0, 2), (proc.returncode, text, proc.stderr)
        outcomes[proc.returncode] += 1
        if proc.returncode == 2:
            lines = proc.stderr.decode(errors="replace").splitlines()
            assert len(lines) == 1, (text, lines)
            assert re.match(re.escape(str(cfg)) + r":\d+: error: ", lines[0]), (text, lines)
    assert outcomes[2] > 0  # the mangling does produce errors
