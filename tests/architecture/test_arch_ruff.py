"""ruff over the whole tree with the rules of ruff.toml (docs/dev/architecture.md says which and
why). A failure lists each finding as ruff prints it: file:line:col: code message."""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
RUFF = [sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise"]


def ruff(*args, cwd=REPO):
    return subprocess.run(RUFF + list(args), cwd=cwd, capture_output=True, text=True, timeout=120)


def test_the_tree_is_clean_under_ruff():
    r = ruff(".")
    if r.returncode != 0:
        pytest.fail("ruff (ruff.toml) finds:\n" + r.stdout + r.stderr
                    + "fix them, or see docs/dev/architecture.md#ruff for the rules", pytrace=False)


def test_ruff_names_file_line_column_and_rule_of_a_bug(tmp_path):
    # the repository's rules on a file of two bugs: an undefined name and an unused import
    (tmp_path / "ruff.toml").write_text((REPO / "ruff.toml").read_text())
    (tmp_path / "bad.py").write_text("import os\n\n\ndef f():\n    return undefined_name\n")
    r = ruff(".", cwd=tmp_path)
    assert r.returncode == 1
    assert "bad.py:1:8: F401" in r.stdout, r.stdout
    assert "bad.py:5:12: F821 Undefined name `undefined_name`" in r.stdout, r.stdout
