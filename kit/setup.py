"""Builds the test kit's wheel from a checkout of mip-logger (docs/test-kit.md).

The wheel holds the repository's own packages as they are (stc, plcharness, mipcosim, mippeer:
one model of each thing, nothing copied into kit/) plus what they find in a checkout:
the runtime's C sources and headers (plcharness/_runtime: every user program is compiled
against them), libmipcosim.so (mipcosim/_lib: the emulator core and the co-simulation kernel,
compiled here with the C compiler of the machine), st_lib's ST sources (mipcosim/_st_lib) and
the docs' sequence-diagram generator (mipkit/_seqdiag.py).
"""
import atexit
import os
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
PACKAGES = {"stc": "translator/stc", "plcharness": "runtime_shim/harness/plcharness",
            "mipcosim": "cosim/mipcosim", "mippeer": "peers/mippeer"}


def _tree(src: Path, dst: Path, patterns=("*.py", "*.lark", "*.h", "*.c", "*.st")):
    for f in sorted(src.rglob("*")):
        if f.is_file() and "__pycache__" not in f.parts and any(f.match(p) for p in patterns):
            out = dst / f.relative_to(src)
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, out)


def _cc(args):
    cmd = shlex.split(os.environ.get("CC", "cc")) + args
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"mip-logger-kit: compiling failed: {' '.join(cmd)}\n{r.stderr}")


class BuildKit(build_py):
    def run(self):
        missing = [p for p in list(PACKAGES.values()) + ["st_lib", "emulator/src/mipemu.c",
                                                          "cosim/src/mipcosim.c",
                                                          "runtime_shim/src"]
                   if not (REPO / p).exists()]
        if missing:
            raise SystemExit(f"mip-logger-kit: build it from a checkout of mip-logger "
                             f"(pip install CHECKOUT/kit): {REPO / missing[0]} missing")
        super().run()
        out = Path(self.build_lib)
        for name, src in PACKAGES.items():
            _tree(REPO / src, out / name)
        rt = out / "plcharness" / "_runtime"
        _tree(REPO / "runtime_shim" / "src", rt / "src")
        _tree(REPO / "runtime_shim" / "include", rt / "include")
        _tree(REPO / "st_lib", out / "mipcosim" / "_st_lib", ("*.st",))
        shutil.copyfile(REPO / "docs" / "tools" / "seqdiag.py", out / "mipkit" / "_seqdiag.py")
        lib = out / "mipcosim" / "_lib"
        lib.mkdir(parents=True, exist_ok=True)
        tmp = Path(self.build_temp if hasattr(self, "build_temp") else out) / "kit-obj"
        tmp.mkdir(parents=True, exist_ok=True)
        emu = tmp / "mipemu.o"
        _cc(["-std=c11", "-D_POSIX_C_SOURCE=200809L", "-O2", "-fPIC", f"-I{REPO / 'emulator/include'}",
             "-c", str(REPO / "emulator/src/mipemu.c"), "-o", str(emu)])
        _cc(["-std=c11", "-D_GNU_SOURCE", "-O2", "-fPIC", "-shared",
             f"-I{REPO / 'cosim/include'}", f"-I{REPO / 'emulator/include'}",
             "-o", str(lib / "libmipcosim.so"), str(REPO / "cosim/src/mipcosim.c"), str(emu), "-lm"])


class BinaryDistribution(Distribution):
    """The wheel carries a shared library: tag it for this platform."""

    def has_ext_modules(self):
        return True


# build outputs go to a temporary directory, never into the checkout (which may be read-only,
# or shared by parallel installs)
_TMP = tempfile.mkdtemp(prefix="mip-logger-kit-build-")
atexit.register(shutil.rmtree, _TMP, True)
setup(cmdclass={"build_py": BuildKit}, distclass=BinaryDistribution,
      options={"build": {"build_base": _TMP}, "egg_info": {"egg_base": _TMP}})
