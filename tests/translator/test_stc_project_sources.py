"""The project's own ST (st_lib/, plc/) must translate with stc and its C must compile with
-std=c99 -Wall -Wextra -Werror."""
import glob
import os
import subprocess

import pytest

import stc_harness as H
from mipprograms.image import program_files

STLIB = os.path.join(H.ROOT, "st_lib")
PLC = os.path.join(H.ROOT, "plc")
PROGRAMS = sorted(p for p in glob.glob(os.path.join(PLC, "*.st"))
                  if not os.path.basename(p).startswith("PLC_"))   # PLC_*.st: the programs' helpers


def _compile(outdir):
    with open(os.path.join(outdir, "SOURCES.txt")) as f:
        for c in f.read().split():
            p = subprocess.run(["cc"] + H.CFLAGS + ["-c", "-o", os.devnull, os.path.join(outdir, c)],
                               capture_output=True, text=True)
            assert p.returncode == 0, f"{c}:\n{p.stderr}"


@pytest.mark.parametrize("libs", [("core",), ("core", "chain")], ids=["core", "core+chain"])
def test_st_lib_translates_and_compiles(libs, tmp_path):
    """Each library (the core alone, the chain on the core) in its import order."""
    from mipcosim.libraries import all_files
    out = str(tmp_path / "o")
    r = H.run_stc(["-o", out] + [os.path.join(STLIB, f) for f in all_files(STLIB, libs)])
    assert r.returncode == 0, r.stderr
    _compile(out)


@pytest.mark.skipif(not PROGRAMS, reason="plc/ has no programs yet")
@pytest.mark.parametrize("prog", PROGRAMS, ids=os.path.basename)
def test_plc_program_translates_and_compiles(prog, tmp_path):
    out = str(tmp_path / "o")
    extra = sorted(glob.glob(os.path.join(PLC, "PLC_*.st")))     # the helpers, PLC_Logger.st first
    files = [str(f) for f in program_files(os.path.basename(prog)[:-3])]   # logic, image
    r = H.run_stc(["-I", os.path.join(STLIB, "core"), "-I", os.path.join(STLIB, "chain"), "-o", out]
                  + extra + files)
    assert r.returncode == 0, r.stderr
    _compile(out)
