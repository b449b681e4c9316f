"""Statements in the docs that drift when the code changes (issue 44): lists of what exists
(folders, st_lib files, blocks) are compared with the tree, and each limitation a page states
("not yet", "needs X", "only", "cannot") is either compared here with the code it describes or
named with the test that fails when the limitation goes away (LIMITATIONS below)."""
from __future__ import annotations

import re
import subprocess
import sys

import pytest

from docs_helpers import REPO

sys.path.insert(0, str(REPO / "dist"))
import mkdist  # noqa: E402

NUMBERS = {w: i for i, w in enumerate("zero one two three four five six seven eight nine ten "
                                      "eleven twelve".split())}


def section(text, heading):
    """The text under a markdown heading, up to the next heading of any level."""
    m = re.search(rf"^#+ {re.escape(heading)}\s*$(.*?)(?=^#|\Z)", text, re.M | re.S)
    assert m, f"no section {heading!r}"
    return m.group(1)


def table_first_column(text, header):
    """The first cells of the markdown table whose header row starts with `| header |`."""
    lines = text.splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith(f"| {header} |"))
    cells = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells.append(line.split("|")[1].strip())
    return cells


def public_blocks():
    """The function blocks of st_lib an application calls: FUNCTION_BLOCKs whose header does
    not call them internal."""
    out = []
    for f in sorted((REPO / "st_lib").glob("*.st")):
        text = f.read_text()
        fb = re.search(r"^FUNCTION_BLOCK (\w+)", text, re.M)
        purpose = re.search(r"@purpose\s+(\S+)", text)
        if fb and not (purpose and purpose.group(1).startswith("Internal")):
            out.append(fb.group(1))
    return out


def tracked_top_folders():
    out = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                         timeout=60)
    if out.returncode != 0:
        pytest.skip(f"not a git checkout (git ls-files: {out.stderr.strip()[:80]})")
    return {p.split("/")[0] for p in out.stdout.splitlines()
            if "/" in p and not p.startswith(".")}


# ----------------------------------------------------------------------- lists of what exists

def test_readme_folder_table_lists_every_top_level_folder():
    named = set()
    for cell in table_first_column((REPO / "README.md").read_text(), "folder"):
        named |= {m.rstrip("/") for m in re.findall(r"`([^`]+/)`", cell)}
    named = {n.split("/")[0] for n in named}
    folders = tracked_top_folders()
    assert folders - named == set(), \
        f"README.md's folder table does not name {sorted(folders - named)}"
    assert named - folders == set(), \
        f"README.md's folder table names {sorted(named - folders)}, which the checkout lacks"


def test_st_lib_readme_table_lists_every_file_in_import_order():
    order = [f.split("/")[-1] for f in mkdist.import_order()[0]]
    rows = [c.strip("`") for c in table_first_column((REPO / "st_lib" / "README.md").read_text(),
                                                    "file")]
    assert [r for r in rows if r.endswith(".st")] == order, (
        "st_lib/README.md's file table is not every st_lib/*.st in the import order "
        f"(`dist/mkdist.py --import-order`): missing {sorted(set(order) - set(rows))}, "
        f"extra {sorted(set(rows) - set(order) - {'PROTOCOL.md'})}")


@pytest.mark.parametrize("page,where", [
    ("st_lib/README.md", None),
    ("docs/README.md", "- **`st_lib/`**"),
    ("README.md", "| `st_lib/` |"),
])
def test_pages_name_every_public_block(page, where):
    text = (REPO / page).read_text()
    if where is None:       # st_lib/README.md: its introduction, before the file table
        part = text.split("\n## ", 1)[0]
    else:                   # the paragraph (or table row) that introduces st_lib/
        i = text.index(where)
        part = text[i:text.find("\n- **", i + 1) if where.startswith("-") else text.find("\n", i)]
    missing = [b for b in public_blocks() if b not in part]
    assert not missing, f"{page}: where it introduces the blocks it does not name {missing}"
    for word in re.findall(r"\b(\w+) blocks\b", part, re.I):
        n = NUMBERS.get(word.lower(), int(word) if word.isdigit() else None)
        if n is not None:
            assert n == len(public_blocks()), \
                f"{page}: says {word} blocks; st_lib has {len(public_blocks())}: {public_blocks()}"


# ------------------------------------------------------------ stated limitations, against code

def test_kit_limitations_say_nothing_of_retain_that_plcrt_build_does():
    """docs/test-kit.md, "Not (yet) in the kit": it said warm restarts need stc (matiec builds
    keeping no RETAIN) after plcrt-build had learnt to keep them (commit cdf4aba;
    tests/runtime/test_rt_matiec.py runs a matiec build's warm restart where iec2c is)."""
    from plcharness import build
    keeps = callable(getattr(build, "matiec_retained", None))
    limits = section((REPO / "docs" / "test-kit.md").read_text(), "Not (yet) in the kit")
    claims = re.search(r"RETAIN|warm (or kill -9 )?restart", limits)
    if keeps:
        assert not claims, ("docs/test-kit.md, Not (yet) in the kit: states a RETAIN limitation, "
                            f"but plcrt-build keeps RETAIN of matiec builds: {claims.group(0)!r}")
    else:
        assert claims, "plcrt-build keeps no RETAIN of matiec builds: say so in the kit's limits"


def test_guarantee_table_window_row_matches_mip_sender():
    """docs/protocol.md's guarantee table said window 2 runs "not `xRetained`"; MIP_Sender's
    header says under which settings uWindow 2 falls back to 1 (tests/st_lib/
    test_lib_window_warm.py runs window 2 with xRetained through warm restarts)."""
    sender = (REPO / "st_lib" / "MIP_Sender.st").read_text()
    row = re.search(r"^\s*\| uWindow .*$", sender, re.M).group(0)
    fallback = re.search(r"PROTOCOL\.md P27;([^)]*)\)", row).group(1)
    table = (REPO / "docs" / "protocol.md").read_text()
    cell = re.search(r"^\| `uWindow` = 2 \| ([^|]*)\|", table, re.M).group(1)
    for word in ("spontaneous", "dynamic"):
        assert (word in fallback) == (word in cell), \
            f"docs/protocol.md's uWindow row and MIP_Sender's uWindow ({fallback.strip()}) differ on {word}"
    restricted = "retain" in fallback.lower()
    assert ("not `xRetained`" in cell) == restricted, (
        f"docs/protocol.md's uWindow row says {cell.strip()!r}; MIP_Sender's uWindow falls back "
        f"to 1 for: {fallback.strip()}")


def test_guarantee_table_cold_restart_row_names_what_the_caller_must_do():
    """The cold-restart row holds only for a caller that acknowledges after the hand-over
    (tests/chain/test_chain_central_cold.py runs it with the note peer against plc/central.st,
    with and without the hand-over)."""
    table = (REPO / "docs" / "protocol.md").read_text()
    row = re.search(r"^\| cold restart \|.*$", table, re.M).group(0)
    assert "xAckByCaller" in row and "xRecordProcessed" in row
    gen = (REPO / "plc" / "central.st").read_text()
    assert "xAckByCaller := xHandOver" in gen and "(pFlags AND 16#0020)" in gen, \
        "plc/central.st no longer hands over with flags bit 5: change the guarantee table's row"
    assert (REPO / "tests" / "chain" / "test_chain_central_cold.py").is_file()
