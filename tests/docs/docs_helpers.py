"""Shared paths and a runner for the documentation tools (tests/docs/)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from mipcosim.libraries import all_files

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "docs" / "tools"
PY = sys.executable
# both libraries' files, the core's then the chain's, each in its import order
ST_LIB = [str(REPO / "st_lib" / f) for f in all_files(REPO / "st_lib")]
XSD = REPO / "build" / "docs" / "tc6_xml_v201.xsd"
# the co-simulation kernel (its emulator core runs the docs' chains: docs/tools/chainsim.py)
KERNEL_SO = REPO / "build" / "cosim" / "libmipcosim.so"


def tool(name, *args, cwd=REPO):
    """Runs docs/tools/<name>.py; returns the CompletedProcess (text)."""
    return subprocess.run([PY, str(TOOLS / f"{name}.py"), *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def rel(paths):
    return [str(Path(p).relative_to(REPO)) for p in paths]


def refused(name, *args, cwd=REPO):
    """Runs docs/tools/<name>.py on input it must refuse: exit 1; returns the CompletedProcess
    (the caller checks its one line)."""
    r = tool(name, *args, cwd=cwd)
    assert r.returncode == 1, r.stderr
    return r
