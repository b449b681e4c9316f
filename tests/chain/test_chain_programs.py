"""The example programs: generated files up to date, compile with matiec too (where
installed), and the committed runtime configs load."""
import subprocess
from pathlib import Path

import pytest

from mipcosim import programs as L
from plcharness.build import build_program, matiec_available

REPO = Path(__file__).resolve().parents[2]
PROGRAMS = [("outstation", False), ("central", False), ("outstation", True), ("central", True),
            ("central_many", False)]


def test_chain_generated_programs_are_up_to_date(tmp_path):
    from mipprograms import gen
    assert gen.main(["-o", str(tmp_path)]) == 0
    for name in ("outstation.st", "central.st", "outstation_bidi.st", "central_bidi.st",
                 "central_many.st", "outstation_soe.st", "central_soe.st", "central_push.st"):
        assert (tmp_path / name).read_text() == (REPO / "plc" / name).read_text(), \
            f"plc/{name} differs from what plc/gen_programs.py writes: run it and commit"


@pytest.mark.skipif(not matiec_available(),
                    reason="iec2c not on PATH (set PATH and MATIEC_LIB to compile with matiec)")
@pytest.mark.parametrize("role,bidi", PROGRAMS, ids=[f"{r}{'-bidi' if b else ''}" for r, b in PROGRAMS])
def test_chain_programs_compile_with_matiec(tmp_path, role, bidi):
    res = build_program(L.program_sources(role, bidi), tmp_path / "out", compiler="matiec")
    assert res.executable.is_file()


@pytest.mark.parametrize("conf,role", [("plc/outstation.conf", "outstation"),
                                       ("plc/central.conf", "central"),
                                       ("plc/central_many.conf", "central_many"),
                                       ("plc/openplc/outstation-mbconfig.cfg", "outstation"),
                                       ("plc/openplc/central-mbconfig.cfg", "central")])
def test_chain_committed_configs_load(tmp_path, conf, role):
    res = build_program(L.program_sources(role, False), tmp_path / "out")
    p = subprocess.run([str(res.executable), "-c", str(REPO / conf), "--check"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


def test_chain_config_error_is_one_line(tmp_path):
    res = build_program(L.program_sources("outstation", False), tmp_path / "out")
    bad = tmp_path / "bad.conf"
    bad.write_text(L.outstation_config(15021).replace("size = 125", "size = 126"))
    p = subprocess.run([str(res.executable), "-c", str(bad), "--check"], capture_output=True,
                       text=True)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and f"{bad}:" in p.stderr and "error:" in p.stderr
