"""stc's three semantics through the harness and plcrt-build: --semantics / PLCRT_SEMANTICS
take matiec, openplc and iec, and a program given an OpenPLC mbconfig.cfg is built with
OpenPLC's matiec fork's values (issue 26). The probe: F_TRIG's first call with CLK FALSE gives
Q in upstream matiec only."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from plcharness import Plc
from plcharness.build import BuildError, build_program, is_openplc_config
from miptest.rt import one_task, stc_works

pytestmark = pytest.mark.skipif(not stc_works(), reason="stc (.venv/bin/stc) is not installed: "
                                "run `make venv`")

FTRIG = one_task("""
PROGRAM MAIN
VAR f : F_TRIG; q : BOOL; END_VAR
f(CLK := FALSE);
q := f.Q;
END_PROGRAM
""")

MBCONFIG = '''Num_Devices = "0"
Polling_Period = "100"
Timeout = "1000"
'''

WANT = {"matiec": 1, "openplc": 0, "iec": 0}


@pytest.mark.parametrize("semantics", ["matiec", "openplc", "iec"])
def test_semantics_argument(semantics, st_file, tmp_path):
    plc = Plc.build([st_file(FTRIG)], workdir=tmp_path, compiler="stc", semantics=semantics)
    plc.scan()
    assert plc["MAIN.q"] == WANT[semantics]


@pytest.mark.parametrize("semantics", ["openplc", "iec"])
def test_plcrt_semantics_environment(semantics, st_file, tmp_path, monkeypatch):
    monkeypatch.setenv("PLCRT_SEMANTICS", semantics)
    plc = Plc.build([st_file(FTRIG)], workdir=tmp_path, compiler="stc")
    plc.scan()
    assert plc["MAIN.q"] == WANT[semantics]


def test_openplc_mbconfig_builds_with_the_fork_semantics(st_file, tmp_path, monkeypatch):
    monkeypatch.delenv("PLCRT_SEMANTICS", raising=False)
    cfg = tmp_path / "mbconfig.cfg"
    cfg.write_text(MBCONFIG)
    assert is_openplc_config(cfg)
    plc = Plc.build([st_file(FTRIG)], workdir=tmp_path / "a", compiler="stc", config=cfg)
    plc.scan()
    assert plc["MAIN.q"] == 0
    # without the OpenPLC config: stc's default, upstream matiec
    plc = Plc.build([st_file(FTRIG)], workdir=tmp_path / "b", compiler="stc")
    plc.scan()
    assert plc["MAIN.q"] == 1


def test_plcrt_config_is_not_openplc(tmp_path):
    cfg = tmp_path / "x.conf"
    cfg.write_text("# plcrt\n[device out]\nhost = 127.0.0.1\n")
    assert not is_openplc_config(cfg)
    assert not is_openplc_config(tmp_path / "missing.cfg")


def test_bad_semantics_is_one_line(st_file, tmp_path, monkeypatch):
    monkeypatch.setenv("PLCRT_SEMANTICS", "beremiz")
    with pytest.raises(BuildError) as e:
        build_program([st_file(FTRIG)], tmp_path / "out", compiler="stc")
    assert str(e.value) == "semantics 'beremiz': error: give matiec, openplc or iec"


def test_plcrt_build_takes_openplc(st_file, tmp_path):
    exe = Path(sys.executable).parent / "plcrt-build"
    if not exe.is_file():
        pytest.skip("plcrt-build is not installed in the venv: run `make venv`")
    env = dict(os.environ)
    env.pop("PLCRT_SEMANTICS", None)
    p = subprocess.run([str(exe), "--semantics=openplc", "-o", str(tmp_path / "out"),
                        str(st_file(FTRIG))], capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    p = subprocess.run([str(exe), "--semantics=fork", "-o", str(tmp_path / "out2"),
                        str(st_file(FTRIG))], capture_output=True, text=True, env=env)
    assert p.returncode == 2 and "invalid choice: 'fork'" in p.stderr
    assert "Traceback" not in p.stderr
