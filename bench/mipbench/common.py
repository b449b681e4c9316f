"""What every figure shares: the paths, time units, the output lines (OK/MISSED/.../ERROR),
running a program, the machine line, a server process started by the bench, peak memory and
whether the co-simulation is available."""
from __future__ import annotations

import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from mipcosim.kernel import MS, SEC  # noqa: F401 (the bench modules take them from here)
from mipcosim.programs import LIB_FILES   # st_lib in import order, the one list
from plcharness import procs

REPO = Path(__file__).resolve().parents[2]   # bench/mipbench/common.py, installed editable
BUILD = REPO / "build" / "bench"
EMU = REPO / "build" / "emulator" / "mip-emulator"
COSIM_LIB = REPO / "build" / "cosim" / "libmipcosim.so"
STC = REPO / ".venv" / "bin" / "stc"
PY = sys.executable
ST_LIB = [REPO / "st_lib" / f for f in LIB_FILES]
PAIR_ST = REPO / "bench" / "st" / "bench_pair.st"
PAYLOAD = 122                      # payload registers of a full chunk (123 - record counter)

ERRORS: list[str] = []


class BenchError(Exception):
    pass


def line(name, text, status):
    print(f"{name}: {text} {status}", flush=True)


def error(name, why):
    ERRORS.append(name)
    line(name, f"not measured: {why}", "ERROR")


def run(cmd, timeout=600, env=None, **kw):
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout,
                       env=env, **kw)
    if p.returncode != 0:
        msg = (p.stderr.strip() or p.stdout.strip() or f"exit status {p.returncode}").splitlines()
        raise BenchError(f"{Path(str(cmd[0])).name}: {msg[-1] if msg else ''}")
    return p.stdout


def first_line(cmd):
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30)
        return (out.stdout or out.stderr).strip().splitlines()[0]
    except (OSError, IndexError, subprocess.SubprocessError):
        return "absent"


# ---------------------------------------------------------------- machine

def matiec_env():
    """PATH/MATIEC_LIB for iec2c, or None when it is not installed (CI) or BENCH_MATIEC=off."""
    env = dict(os.environ)
    if env.get("BENCH_MATIEC") == "off":
        return None
    if not shutil.which("iec2c", path=env.get("PATH")) and Path("/opt/src/matiec/iec2c").is_file():
        env["PATH"] = "/opt/src/matiec:" + env.get("PATH", "")
        env.setdefault("MATIEC_LIB", "/opt/src/matiec/lib")
    iec2c = shutil.which("iec2c", path=env.get("PATH"))
    if not iec2c:
        return None
    env.setdefault("MATIEC_LIB", str(Path(iec2c).parent / "lib"))
    return env


def machine():
    cpu = "unknown"
    try:
        for l in Path("/proc/cpuinfo").read_text().splitlines():
            if l.startswith("model name"):
                cpu = l.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        load = "%.2f %.2f %.2f" % os.getloadavg()
    except OSError:
        load = "?"
    cc = os.environ.get("CC", "cc")
    print(f"machine: cpu={cpu!r} cores={os.cpu_count()} kernel={platform.release()} "
          f"load_avg={load}")
    menv = matiec_env()
    iec2c = "absent"
    if menv:
        iec2c = shutil.which("iec2c", path=menv["PATH"])
        iec2c = f"{first_line([iec2c, '-v'])} ({iec2c})"
    print(f"machine: cc={first_line([cc, '--version'])!r} python={platform.python_version()} "
          f"valgrind={first_line(['valgrind', '--version'])} "
          f"libmodbus={first_line(['pkg-config', '--modversion', 'libmodbus'])} "
          f"stc={first_line([STC, '--version'])!r} iec2c={iec2c!r}",
          flush=True)


# ---------------------------------------------------------------- helpers: processes

class Server(procs.Server):
    """A server process started by the bench (plcharness.procs.Server: ready at a line that
    matches `ready`); stopped (SIGTERM, then SIGKILL) on exit."""

    def __init__(self, cmd, ready=r"listening", timeout=30):
        try:
            super().__init__(cmd, ready, timeout)
        except procs.NotReady as e:
            raise BenchError(str(e)) from None
        self.p = self.proc


RSS_RUN = BUILD / "rss_run"


def read_rss(path: Path) -> int:
    m = re.search(r"maxrss_kib=(\d+)", path.read_text() if path.is_file() else "")
    if not m:
        raise BenchError(f"no peak memory in {path.name}")
    return int(m.group(1))


def run_rss(cmd, timeout=600) -> int:
    """Runs cmd to completion under bench/rss_run.c; its max RSS in KiB."""
    with tempfile.NamedTemporaryFile(dir=BUILD, suffix=".rss") as f:
        run([RSS_RUN, f.name, *cmd], timeout=timeout)
        return read_rss(Path(f.name))



def cosim_available():
    if not COSIM_LIB.is_file():
        return False, f"{COSIM_LIB.relative_to(REPO)} missing"
    try:
        import mipcosim.sim  # noqa: F401
    except Exception as e:  # noqa: BLE001 - any import failure means "not available"
        return False, f"mipcosim does not import ({type(e).__name__}: {e})"
    return True, ""


def cosim_missing(name, pending):
    """True, with the figure's line said, when the co-simulation cannot run: PENDING for a
    figure that waits for it to be built, else an ERROR."""
    ok, why = cosim_available()
    if ok:
        return False
    if pending:
        line(name, f"pending: cosim not built ({why})", "PENDING")
    else:
        error(name, why)
    return True


def failure(e):
    """A figure's exception as one line: its type and the last line of its message."""
    msg = str(e).strip().splitlines()
    return f"{type(e).__name__}: {msg[-1] if msg else ''}"
