"""Cross-check with the reference compiler: every accept-corpus file must also be accepted by
matiec (iec2c) and its C must compile; every reject-corpus file must be rejected by matiec too,
except files marked (* MATIEC-ACCEPTS: reason *), where the dialect is deliberately stricter.

iec2c is looked up in $IEC2C or on PATH (MATIEC_LIB or <iec2c dir>/lib for its library); the
tests are skipped, with that reason, when it is absent (as in CI)."""
import glob
import os
import subprocess

import pytest

import stc_harness as H

IEC2C, MATIEC_LIB = H.find_iec2c()
needs_matiec = pytest.mark.skipif(
    not (IEC2C and MATIEC_LIB),
    reason="iec2c not found (set IEC2C or put iec2c on PATH, and MATIEC_LIB) - matiec cross-check skipped")

ACCEPT = sorted(glob.glob(os.path.join(H.HERE, "accept", "*.st")))
REJECT = sorted(glob.glob(os.path.join(H.HERE, "reject", "*.st")))


def _id(p):
    return os.path.splitext(os.path.basename(p))[0]


def _iec2c(path, outdir):
    os.makedirs(outdir, exist_ok=True)
    return subprocess.run([IEC2C, "-I", MATIEC_LIB, "-T", outdir, path],
                          capture_output=True, text=True, timeout=60)


@needs_matiec
@pytest.mark.parametrize("path", ACCEPT, ids=_id)
def test_matiec_accepts(path, tmp_path):
    r = _iec2c(path, str(tmp_path))
    assert r.returncode == 0, f"matiec rejects {path}:\n{r.stdout}{r.stderr}"
    # matiec names the files after the configuration and resources; POUS.c is #included
    for c in sorted(f for f in os.listdir(str(tmp_path)) if f.endswith(".c") and f != "POUS.c"):
        p = subprocess.run(["cc", "-c", "-w", "-I", os.path.join(MATIEC_LIB, "C"), "-o", os.devnull,
                            os.path.join(str(tmp_path), c)], capture_output=True, text=True)
        assert p.returncode == 0, f"matiec's C of {path} does not compile:\n{p.stderr}"


@needs_matiec
@pytest.mark.parametrize("path", REJECT, ids=_id)
def test_matiec_rejects(path, tmp_path):
    with open(path) as f:
        text = f.read()
    r = _iec2c(path, str(tmp_path))
    if "(* MATIEC-ACCEPTS:" in text:
        assert r.returncode == 0, "marked MATIEC-ACCEPTS but matiec rejects it: remove the mark"
        mark = text.split("(* MATIEC-ACCEPTS:", 1)[1].split("*)", 1)[0]
        if "C does not compile" in mark:
            # the reason stc refuses it must hold: matiec's C of it fails to compile
            # a file without a CONFIGURATION gives only POUS.c: compile it the way a
            # resource file includes it
            unit = os.path.join(str(tmp_path), "unit.c")
            with open(unit, "w") as u:
                u.write('#include "iec_std_lib.h"\n#include "accessor.h"\n'
                        '#include "POUS.h"\n#include "POUS.c"\n')
            results = [subprocess.run(["cc", "-c", "-w", "-I", os.path.join(MATIEC_LIB, "C"),
                                       "-I", str(tmp_path), "-o", os.devnull, unit],
                                      capture_output=True, text=True).returncode]
            assert any(rc != 0 for rc in results), \
                f"marked 'C does not compile' but matiec's C of {path} compiles: remove the mark"
    else:
        assert r.returncode != 0, f"matiec accepts {path}, so stc should too"
