"""One import order of st_lib: dist/mkdist.py computes it (the release archive stores and lists
the files in it); every page that names several st_lib files names them in that order, and the
lists of it (blocks.md, the archive's README.txt, st_lib/README.md) are exactly it."""
from __future__ import annotations

import os
import re
import subprocess

import pytest
from mipdist import mkdist

from docs_helpers import PY, REPO
from test_docs_commands import PAGES, rel

FILE = re.compile(r"\bMIP_\w+\.st\b")
LISTED = re.compile(r"^\s*\d+\.\s+`(st_lib/MIP_\w+\.st)`", re.M)


@pytest.fixture(scope="module")
def order():
    out = subprocess.run([PY, str(REPO / "dist" / "mkdist.py"), "--import-order"], cwd=REPO,
                         capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"))
    assert out.returncode == 0, out.stderr
    files = out.stdout.split()
    assert sorted(files) == sorted(str(p.relative_to(REPO)) for p in (REPO / "st_lib").glob("*/*.st"))
    assert files == mkdist.import_order()[0]
    return files


def test_the_lists_are_the_order(order):
    for page in (REPO / "docs" / "blocks.md", REPO / "st_lib" / "README.md"):
        listed = LISTED.findall(page.read_text())
        assert listed == order, f"{rel(page)}: its import order list is not `dist/mkdist.py " \
                                f"--import-order`:\n" + "\n".join(f"{i}. `{f}`" for i, f in enumerate(order, 1))
    from mipcosim.programs import LIB_FILES
    assert [f"st_lib/{f}" for f in LIB_FILES] == order, \
        "cosim/mipcosim/programs.py: LIB_FILES is not the import order of dist/mkdist.py"
    readme = mkdist.readme(order, "0.0.0")
    assert re.findall(r"^\s+\d+\. (st_lib/\S+)$", readme, re.M) == order


@pytest.mark.parametrize("page", PAGES, ids=rel)
def test_pages_name_st_lib_files_in_import_order(page, order):
    """A paragraph, table or block that names three or more st_lib files names them in the
    import order, so no page can state another order."""
    index = {f.split("/")[-1]: i for i, f in enumerate(order)}
    text = page.read_text()
    for n, chunk in enumerate(re.split(r"\n\s*\n", text)):
        seen = []
        for name in FILE.findall(chunk):
            if name in index and name not in seen:
                seen.append(name)
        if len(seen) >= 3:
            assert seen == sorted(seen, key=index.get), (
                f"{rel(page)}: names st_lib files in another order than the import order "
                f"({', '.join(seen)}); the order is `dist/mkdist.py --import-order`: "
                f"{', '.join(f.split('/')[-1] for f in order)}\n--- in\n{chunk[:800]}")

