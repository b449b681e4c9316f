"""The interop table in docs/protocol.md: generated from the committed results of a matrix run
(interop/results.json), complete (every cell of the matrix) and well-formed; the generator
touches nothing outside its markers and fails with one line where it cannot work."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from mipinterop import docs
from mipinterop.matrix import FAULTS, OURS, READINGS, all_cells, pipelined_applies

REPO = Path(__file__).resolve().parents[2]
COMMITTED = REPO / "interop" / "results.json"
CELL = re.compile(r"^(complete( after [A-Z_, ]+)?|error [A-Z_#0-9]+ after \d+\.\d s|\*\*FAIL\*\* .+)"
                  r"( \(\d+ blocks lost\))?$")


def test_committed_table_is_what_the_generator_makes_from_the_committed_results():
    doc = json.loads(COMMITTED.read_text())
    assert sorted(r["cell"] for r in doc["results"]) == sorted(c.key for c in all_cells())
    section = docs.section(docs.DOC.read_text())
    assert section is not None, "docs/protocol.md has no interop-matrix section"
    assert section == docs.table(doc), \
        "docs/protocol.md's table is stale: run python -m mipinterop --write-docs interop/results.json"


def test_table_is_well_formed():
    section = docs.section(docs.DOC.read_text())
    rows = [l for l in section.splitlines() if l.startswith("| ") and not l.startswith("| ours")]
    assert len(rows) == len(OURS) * len(READINGS) * len(FAULTS)
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert len(cells) == 3 + len(docs.COLUMNS), line
        for (layout, mode), c in zip(docs.COLUMNS, cells[3:]):
            if mode == "pipelined" and not pipelined_applies(
                    "sender" if line.startswith("| our sender") else "receiver", layout):
                assert c == "-", f"cell {c!r} of row {line!r}: no stream of ours to pipeline"
            else:
                assert CELL.match(c), f"cell {c!r} of row {line!r}"


def test_every_committed_result_follows_its_own_rule():
    """A result marked passed is "complete" or an error within the bound stated in the run."""
    doc = json.loads(COMMITTED.read_text())
    bound = doc["config"]["bound_s"]
    for r in doc["results"]:
        if r["outcome"] == "error":
            assert r["passed"] and r["error_after_s"] <= bound, r
        elif r["outcome"] == "complete":
            assert r["passed"] and all(s == "complete" for s in r["streams"].values()), r
        else:
            assert r["outcome"] == "FAIL" and not r["passed"], r


def _fake_results(text="complete"):
    return {"config": {"records": 6, "timeout_ms": 500, "max_retries": 3, "drive": "spontaneous",
                       "loss": 0.3, "restart_after": 3, "bound_s": 2.5, "bound_factor": 5},
            "seconds": 1.0,
            "results": [{"cell": c.key, "passed": True, "text": text, "outcome": "complete"}
                        for c in all_cells()]}


def test_write_replaces_only_the_marked_section(tmp_path):
    page = tmp_path / "protocol.md"
    page.write_text(f"# Title\n\nbefore\n\n{docs.BEGIN}\nold table\n{docs.END}\n\nafter\n")
    docs.write(_fake_results(), page)
    text = page.read_text()
    assert text.startswith("# Title\n\nbefore\n\n") and text.endswith("\n\nafter\n")
    rows = [l for l in text.splitlines() if l.startswith("| ") and not l.startswith("| ours")]
    assert "old table" not in text and sum(l.count(" complete ") for l in rows) == len(all_cells()) == 88


@pytest.mark.parametrize("body", ["no markers at all\n", f"{docs.END}\n{docs.BEGIN}\n",
                                  f"{docs.BEGIN}\n{docs.BEGIN}\n{docs.END}\n"])
def test_missing_or_broken_markers_are_one_line(tmp_path, body):
    page = tmp_path / "protocol.md"
    page.write_text(body)
    with pytest.raises(docs.DocsError):
        docs.write(_fake_results(), page)
    assert page.read_text() == body


def test_cli_errors_are_one_line(tmp_path):
    run = lambda *a: subprocess.run([sys.executable, "-m", "mipinterop", *a],
                                    capture_output=True, text=True, timeout=60,
                                    cwd=REPO / "interop")
    p = run("--write-docs", str(tmp_path / "missing.json"))
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert p.stderr.strip().startswith("mipinterop: error: ") and len(p.stderr.splitlines()) == 1
    p = run("--out", str(tmp_path / "r.json"), "--cells", "sender/strict/nofault/uni/dynamic")
    assert p.returncode == 2 and "'nofault' is not one of none" in p.stderr
    assert "Traceback" not in p.stderr
