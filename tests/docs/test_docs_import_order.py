"""One import order per library of st_lib: st_lib/<library>/import-order.txt, checked and printed
by dist/mkdist.py (the release archives store and list the files in it); every page that names
several st_lib files names them in that order (the core's before the chain's), and the lists of
it (blocks.md, blocks-chain.md, the archives' README.txt, st_lib/README.md) are exactly it."""
from __future__ import annotations

import os
import re
import subprocess

import pytest
from mipdist import mkdist

from docs_helpers import PY, REPO
from test_docs_commands import PAGES, rel

FILE = re.compile(r"\bMIP_\w+\.st\b")
LISTED = re.compile(r"^\s*\d+\.\s+`(st_lib/(?:core|chain)/MIP_\w+\.st)`", re.M)


@pytest.fixture(scope="module")
def order():
    out = subprocess.run([PY, str(REPO / "dist" / "mkdist.py"), "--import-order"], cwd=REPO,
                         capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"))
    assert out.returncode == 0, out.stderr
    files = out.stdout.split()
    assert sorted(files) == sorted(str(p.relative_to(REPO)) for p in (REPO / "st_lib").glob("*/*.st"))
    assert files == mkdist.import_order(REPO, "core")[0] + mkdist.import_order(REPO, "chain")[0]
    return files


def test_the_lists_are_the_order(order):
    core = [f for f in order if f.startswith("st_lib/core/")]
    chain = [f for f in order if f.startswith("st_lib/chain/")]
    assert core + chain == order and core and chain
    for page, want in ((REPO / "docs" / "blocks.md", core), (REPO / "docs" / "blocks-chain.md", chain),
                       (REPO / "st_lib" / "README.md", order)):
        listed = LISTED.findall(page.read_text())
        assert listed == want, f"{rel(page)}: its import order list is not `dist/mkdist.py " \
                               f"--import-order`:\n" + "\n".join(f"{i}. `{f}`" for i, f in enumerate(want, 1))
    from mipcosim.programs import LIB_FILES
    assert [f"st_lib/{f}" for f in LIB_FILES] == order, \
        "cosim/mipcosim/programs.py: LIB_FILES is not the import order of dist/mkdist.py"
    readme = mkdist.readme(core, "0.0.0")
    assert re.findall(r"^\s+\d+\. (st_lib/\S+)$", readme, re.M) == core
    readme = mkdist.readme_chain(chain, "0.0.0", "0.0.0")
    assert re.findall(r"^\s+\d+\. (st_lib/\S+)$", readme, re.M) == chain


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

