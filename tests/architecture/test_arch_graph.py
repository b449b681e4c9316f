"""The picture of docs/dev/architecture.md is the import graph of today's tree: regenerated, it
is byte for byte the committed one (make docs-imports writes it)."""
from pathlib import Path

import pytest

from mipdocs import importgraph

REPO = Path(__file__).resolve().parents[2]
COMMITTED = REPO / "docs/img/import-graph.svg"


def test_the_committed_import_graph_is_todays(tmp_path):
    out = tmp_path / "import-graph.svg"
    assert importgraph.main(["-o", str(out)]) == 0
    if out.read_bytes() != COMMITTED.read_bytes():
        pytest.fail(f"{COMMITTED.relative_to(REPO)} is not the import graph of the tree: "
                    "`make docs-imports` redraws it", pytrace=False)


def test_an_upward_arrow_is_drawn_red():
    svg = importgraph.render([["top"], ["bottom"]], {("top", "bottom"), ("bottom", "top")},
                             {"top": "t/", "bottom": "b/"})
    down = next(line for line in svg.splitlines() if "top imports bottom" in line)
    up = next(line for line in svg.splitlines() if "bottom imports top" in line)
    assert 'stroke="#5d6d7e"' in down and 'stroke="#c0392b"' in up


def test_a_contracts_file_without_layers_is_one_line_of_error(tmp_path, capsys):
    bad = tmp_path / "contracts.ini"
    bad.write_text("[importlinter]\nroot_packages = stc\n")
    assert importgraph.main(["--contracts", str(bad), "--cycles"]) == 1
    assert capsys.readouterr().err == f"importgraph: error: {bad}: no contract of type = layers\n"
