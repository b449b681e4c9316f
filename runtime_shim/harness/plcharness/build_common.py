"""What the build steps share (build.py, matiec.py, build_cache.py): where the runtime's
sources are, the build's error and result types, and running the C compiler."""
from __future__ import annotations

import os
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNTIME_DIR = HERE.parent.parent  # runtime_shim/
REPO_ROOT = RUNTIME_DIR.parent
# Installed by the test kit (kit/, docs/test-kit.md): the runtime's C sources and headers ship
# inside the package, and there is no checkout around it.
INSTALLED = (HERE / "_runtime" / "src").is_dir()
if INSTALLED:
    RUNTIME_DIR = HERE / "_runtime"
    REPO_ROOT = None
CORE_SOURCES = ["plcrt_core.c", "plcrt_image.c", "plcrt_config.c", "plcrt_master.c", "plcrt_transport.c",
                "plcrt_serial_line.c", "plcrt_slave.c", "plcrt_retain.c"]
GCSE_LIMIT = 512 * 1024  # bytes of a generated C file compiled without -fgcse (see _build_into)
BUILD_FORMAT = "4"  # bump when the generated files change, to invalidate the cache

ELEMENTARY = {
    "BOOL", "BYTE", "SINT", "USINT", "WORD", "INT", "UINT", "DWORD", "DINT", "UDINT",
    "LWORD", "LINT", "ULINT", "REAL", "LREAL", "TIME", "DATE", "TOD", "DT",
    "TIME_OF_DAY", "DATE_AND_TIME", "STRING",
}


class BuildError(Exception):
    """A build step failed; str() is the compiler's message (file:line: error: ...)."""


@dataclass
class Symbol:
    path: str      # upper-case IEC path, CONFIG0.RES0.INSTANCE0.X
    type: str      # INT, WORD[0..147], ENUM:E_STATE, ...
    kind: str      # VAR, VAR_INPUT, ..., LOCATED
    c_ref: str     # C lvalue of the storage (first element for arrays)


@dataclass
class BuildResult:
    outdir: Path
    library: Path
    executable: Path
    compiler: str
    symbols: list[Symbol]
    programs: dict[str, str] = field(default_factory=dict)  # instance path → program type



def _run(cmd, what, cwd=None):
    try:
        proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    except FileNotFoundError as e:
        raise BuildError(f"{what}: cannot run {cmd[0]}: {e.strerror}") from None
    if proc.returncode != 0:
        msg = (proc.stderr.strip() + "\n" + proc.stdout.strip()).strip()
        raise BuildError(f"{what} failed:\n{msg}")
    return proc


def _cc():
    return os.environ.get("CC", "cc")


def _modbus_flags():
    """(cflags, libs) of libmodbus from pkg-config, with Debian's layout as the fallback."""
    try:
        cflags = subprocess.run(["pkg-config", "--cflags", "libmodbus"], capture_output=True,
                                text=True, check=True).stdout.split()
        libs = subprocess.run(["pkg-config", "--libs", "libmodbus"], capture_output=True,
                              text=True, check=True).stdout.split()
        return cflags, libs
    except (OSError, subprocess.CalledProcessError):
        return ["-I/usr/include/modbus"], ["-lmodbus"]


def _compile(cmd, what):
    _run(cmd, what)
