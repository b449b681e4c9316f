"""Shared helpers of the runtime tests (a uniquely named module: every part has its own tests dir)."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from plcharness.build import matiec_available

REPO = Path(__file__).resolve().parents[2]


def stc_works() -> bool:
    stc = Path(sys.executable).parent / "stc"
    if not stc.is_file():
        return False
    probe = subprocess.run([str(stc), "--help"], capture_output=True, text=True)
    return probe.returncode == 0


needs_matiec = pytest.mark.skipif(
    not matiec_available(),
    reason="iec2c not on PATH (set PATH and MATIEC_LIB to run the matiec tests)")


