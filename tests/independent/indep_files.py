"""What the independent checks (tests/independent/, issue 36 item 5) run on and with: the vendor glue
files found by glob (dist/glue/<family>/, picked up as they land), the generated TIA SCL
(stc.scl_out, when the tree has it) and the independent tools, each found or skipped with the
reason a user can act on."""
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
STUBS = HERE / "stubs"
GLUE = REPO / "dist" / "glue"

# the file kinds an integrator copies into each IDE (plain ST and TwinCAT's XML objects)
GLUE_SUFFIXES = {
    "twincat": (".st", ".TcPOU", ".TcDUT", ".TcGVL"),
    "codesys": (".st",),
    "s7": (".scl",),
}

IRONPLC_BUILD = (
    "IronPLC with dialects is not in any registry this CI reaches (crates.io has only "
    "ironplc-parser 0.1.1, without dialects); build it from source: `git clone "
    "https://github.com/ironplc/ironplc`, then in compiler/ `cargo build --bin ironplcc` "
    "(upstream's CONTRIBUTING.md: Rust stable and Cargo; every crate it needs comes from "
    "crates.io), and give the binary as IRONPLCC=/path/to/ironplcc or put it on PATH "
    "(docs/wiring-twincat.md, Independent checks)")

SCL_CHECKER_BUILD = (
    "vscode-simatic-scl (the Langium SCL grammar with name resolution) is on GitHub only, in no "
    "registry this CI reaches; build it: `git clone https://github.com/BjAlvestad/"
    "vscode-simatic-scl`, then in it `npm ci`, `npx langium generate`, `npx tsc -b "
    "tsconfig.src.json` (Node.js 20 or newer), and give the checkout as "
    "SCL_LANGIUM_CHECKOUT=/path/to/vscode-simatic-scl (docs/wiring-s7.md, Independent checks)")


def glue_files(family):
    """The glue files of one family (dist/glue/<family>/**), sorted; [] while there are none."""
    root = GLUE / family
    if not root.is_dir():
        return []
    return sorted(p for p in root.rglob("*")
                  if p.is_file() and p.name.endswith(GLUE_SUFFIXES[family]))


def need_glue(family):
    files = glue_files(family)
    if not files:
        pytest.skip(f"no {family} glue files yet (dist/glue/{family}/**/*"
                    f"{{{','.join(GLUE_SUFFIXES[family])}}}; issue 36 item 2)")
    return files


def st_lib_files(libs=("core", "chain")):
    """st_lib's files of the given libraries (default both), each library's in its import order
    (st_lib/<library>/import-order.txt)."""
    from mipcosim.libraries import all_files
    return [REPO / "st_lib" / f for f in all_files(REPO / "st_lib", libs)]


def ironplcc():
    """Path of an ironplcc that has the codesys and twincat dialects, else skip with the reason."""
    given = os.environ.get("IRONPLCC")
    exe = given or shutil.which("ironplcc")
    if not exe:
        pytest.skip(IRONPLC_BUILD)
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        pytest.fail(f"IRONPLCC={given}: no such executable")
    r = subprocess.run([exe, "dialects"], capture_output=True, text=True, timeout=60)
    if r.returncode != 0 or "twincat" not in r.stdout or "codesys" not in r.stdout:
        pytest.skip(f"{exe} has no codesys/twincat dialects (an old release?); " + IRONPLC_BUILD)
    return exe


def scl_checker():
    """(node, checkout) of a built vscode-simatic-scl, else skip with the reason."""
    checkout = os.environ.get("SCL_LANGIUM_CHECKOUT")
    if not checkout:
        pytest.skip(SCL_CHECKER_BUILD)
    node = shutil.which("node")
    if not node:
        pytest.skip("SCL_LANGIUM_CHECKOUT is given but Node.js (node) is not on PATH")
    if not (Path(checkout) / "out" / "language" / "scl-module.js").is_file():
        pytest.fail(f"SCL_LANGIUM_CHECKOUT={checkout}: not a built checkout (no "
                    f"out/language/scl-module.js); " + SCL_CHECKER_BUILD)
    return node, checkout


def generated_scl(outdir):
    """st_lib as TIA SCL external sources, one .scl per block, written by the generator's own
    command line (stc.scl_out) into outdir; skip while this tree has no generator."""
    if importlib.util.find_spec("stc.scl_out") is None:
        pytest.skip("this tree has no SCL generator yet (stc.scl_out, issue 36 item 3)")
    r = subprocess.run([sys.executable, "-m", "stc.scl_out", "-o", str(outdir),
                        *map(str, st_lib_files())],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 0, f"stc.scl_out failed:\n{r.stderr}"
    files = sorted(Path(outdir).glob("*.scl"))
    assert files, "stc.scl_out wrote no .scl file"
    return files
