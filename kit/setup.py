"""Builds the test kit's wheel from a checkout of mip-logger (docs/test-kit.md).

The wheel holds the repository's own packages as they are (stc, plcharness, mipcosim, mippeer,
mipprobe, mipdocs for the docs' sequence diagrams, mipprograms for mip-glue, stock OpenPLC's
limits and the example programs' generator: one model of each thing, nothing copied into kit/)
plus what they find in a checkout: the runtime's C sources and headers (plcharness/_runtime:
every user program is compiled against them), libmipcosim.so (mipcosim/_lib: the emulator core
and the co-simulation kernel, compiled here with the C compiler of the machine), st_lib's ST
sources (mipcosim/_st_lib) and the Wireshark dissector (mipkit/mipmb.lua).
"""
import atexit
import os
import re
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist

HERE = Path(__file__).resolve().parent
# a checkout (kit/ inside it), or the kit's source archive (`make kit-dist`: the same files
# under _src/)
REPO = HERE.parent if (HERE.parent / "translator" / "stc").is_dir() else HERE / "_src"
# what the wheel is made of, relative to REPO (the source archive carries exactly these)
NEEDED = ["translator/stc", "runtime_shim/harness/plcharness", "runtime_shim/src",
          "runtime_shim/include", "cosim/mipcosim", "cosim/src/mipcosim.c", "cosim/include",
          "emulator/src/mipemu.c", "emulator/src/siprotec.c", "emulator/include", "peers/mippeer", "probe/mipprobe", "st_lib",
          "docs/tools", "plc/mipprograms", "plc/PLC_Logger.st", "plc/PLC_SoeChain.st", "LICENSE"]
NEEDED += ["dist/wireshark/mipmb.lua"]      # the dissector, for the kit's captures (capture.py)
PACKAGES = {"stc": "translator/stc", "plcharness": "runtime_shim/harness/plcharness",
            "mipcosim": "cosim/mipcosim", "mippeer": "peers/mippeer",
            "mipprobe": "probe/mipprobe", "mipprograms": "plc/mipprograms"}


def _tree(src: Path, dst: Path, patterns=None):
    """Every file of src (patterns None: all but compiled Python) into dst."""
    for f in sorted(src.rglob("*")):
        if not f.is_file() or "__pycache__" in f.parts or f.suffix in (".pyc", ".o", ".so"):
            continue
        if patterns is None or any(f.match(p) for p in patterns):
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
        missing = [p for p in NEEDED if not (REPO / p).exists()]
        if missing:
            raise SystemExit(f"mip-logger-kit: build it from a checkout of mip-logger "
                             f"(pip install CHECKOUT/kit) or from the kit's source archive: "
                             f"{REPO / missing[0]} missing")
        super().run()
        out = Path(self.build_lib)
        for name, src in PACKAGES.items():
            _tree(REPO / src, out / name)
        rt = out / "plcharness" / "_runtime"
        _tree(REPO / "runtime_shim" / "src", rt / "src")
        _tree(REPO / "runtime_shim" / "include", rt / "include")
        # both libraries' folders with their import orders (mipcosim.libraries reads them)
        _tree(REPO / "st_lib", out / "mipcosim" / "_st_lib", ("*.st", "import-order.txt"))
        # the types whose member order is the programs' %MW layout (mipprograms.image and
        # image_chain read it)
        for types in ("PLC_Logger.st", "PLC_SoeChain.st"):
            shutil.copyfile(REPO / "plc" / types, out / "mipprograms" / types)
        _tree(REPO / "docs" / "tools", out / "mipdocs", ("*.py", "*.st"))   # the package, not its pyproject
        shutil.copyfile(REPO / "dist" / "wireshark" / "mipmb.lua", out / "mipkit" / "mipmb.lua")
        lib = out / "mipcosim" / "_lib"
        lib.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix="obj-", dir=_TMP))    # not in the wheel
        emu = tmp / "mipemu.o"
        _cc(["-std=c11", "-D_POSIX_C_SOURCE=200809L", "-O2", "-fPIC", f"-I{REPO / 'emulator/include'}",
             "-c", str(REPO / "emulator/src/mipemu.c"), "-o", str(emu)])
        relay = tmp / "siprotec.o"       # the SIPROTEC relay core (mipcosim_relay_add)
        _cc(["-std=c11", "-D_POSIX_C_SOURCE=200809L", "-O2", "-fPIC", f"-I{REPO / 'emulator/include'}",
             "-c", str(REPO / "emulator/src/siprotec.c"), "-o", str(relay)])
        _cc(["-std=c11", "-D_GNU_SOURCE", "-O2", "-fPIC", "-shared",
             f"-I{REPO / 'cosim/include'}", f"-I{REPO / 'emulator/include'}",
             "-o", str(lib / "libmipcosim.so"), str(REPO / "cosim/src/mipcosim.c"), str(emu), str(relay),
             "-lm"])


class SdistKit(sdist):
    """The kit's source archive: kit/ plus the repository's files it is built from (_src/)."""

    def make_release_tree(self, base_dir, files):
        super().make_release_tree(base_dir, files)
        for rel in NEEDED:
            src, dst = REPO / rel, Path(base_dir) / "_src" / rel
            if src.is_dir():
                _tree(src, dst)
            else:
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(src, dst)


def version():
    """The core library's version (st_lib/core/MIP_Version.st), the version of the kit's release."""
    text = (REPO / "st_lib" / "core" / "MIP_Version.st").read_text(encoding="utf-8")
    parts = dict(re.findall(r"\bu(Major|Minor|Patch)\s*:\s*UINT\s*:=\s*(\d+)", text))
    return f"{parts['Major']}.{parts['Minor']}.{parts['Patch']}"


class BinaryDistribution(Distribution):
    """The wheel carries a shared library: tag it for this platform."""

    def has_ext_modules(self):
        return True


# build outputs go to a temporary directory, never into the checkout (which may be read-only,
# or shared by parallel installs)
_TMP = tempfile.mkdtemp(prefix="mip-logger-kit-build-")
atexit.register(shutil.rmtree, _TMP, True)
setup(version=version(), cmdclass={"build_py": BuildKit, "sdist": SdistKit},
      distclass=BinaryDistribution,
      options={"build": {"build_base": _TMP}, "egg_info": {"egg_base": _TMP}})
