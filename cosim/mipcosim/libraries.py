"""The two ST libraries of st_lib/ (issue 46): the protocol core (st_lib/core/) and the chain's
application blocks (st_lib/chain/, built on the core), each with its import order in ONE file,
st_lib/<library>/import-order.txt: every .st file of the folder, one a line, each after the
files it uses. Everything that builds or ships the library reads the order from here (mkdist and
the release archives, the co-simulation, the kit, the tests, the benchmarks, the docs' tools);
`dist/mkdist.py --import-order` checks the file against the files' dependencies."""
from __future__ import annotations

import os
from pathlib import Path

# the libraries in the order they are imported: a library depends only on the ones before it
LIBRARIES = ("core", "chain")
ORDER_FILE = "import-order.txt"


class LibraryError(Exception):
    """One line for the user: FILE[:LINE]: error: MESSAGE."""


def order_entries(root: Path, lib: str) -> list[tuple[int, str]]:
    """[(line, file name)] of root/<lib>/import-order.txt (blank lines and # comments skipped)."""
    if lib not in LIBRARIES:
        raise LibraryError(f"st_lib: error: no library {lib!r} (the libraries: {', '.join(LIBRARIES)})")
    path = Path(root) / lib / ORDER_FILE
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise LibraryError(f"{os.path.relpath(path)}: error: {e.strerror}") from None
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        name = line.split("#", 1)[0].strip()
        if name:
            out.append((n, name))
    return out


def library_files(lib: str, root: Path) -> list[str]:
    """The .st files of one library in import order, relative to root (e.g. core/MIP_Types.st);
    refuses (one line) an order file that names a missing file or one twice."""
    out, seen = [], set()
    for n, name in order_entries(root, lib):
        where = f"{os.path.relpath(Path(root) / lib / ORDER_FILE)}:{n}"
        if name in seen:
            raise LibraryError(f"{where}: error: {name} is listed twice")
        if not name.endswith(".st") or not (Path(root) / lib / name).is_file():
            raise LibraryError(f"{where}: error: {name}: no such .st file in {lib}/")
        seen.add(name)
        out.append(f"{lib}/{name}")
    return out


def all_files(root: Path, libs=LIBRARIES) -> list[str]:
    """The files of the given libraries (default: both), each library's in its import order, the
    core first: what a program that uses the chain's blocks is built with."""
    return [f for lib in libs for f in library_files(lib, root)]
