"""The house's size rule (docs/dev/architecture.md, issue 45): no Python module of ours over
700 lines and no class over 500. A module that grows past it is split before the next feature
lands in it; this test names the file and its length."""
import ast
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MAX_MODULE, MAX_CLASS = 700, 500


def our_python_files():
    out = subprocess.run(["git", "ls-files", "*.py"], cwd=REPO, capture_output=True, text=True,
                         check=True).stdout.split()
    return [REPO / f for f in out if (REPO / f).is_file()]


def test_no_module_over_700_lines():
    files = our_python_files()
    assert len(files) > 100, "git ls-files found too few files: the check would prove nothing"
    over = [(f.relative_to(REPO).as_posix(), n) for f in files
            if (n := len(f.read_text(encoding="utf-8").splitlines())) > MAX_MODULE]
    assert over == [], f"modules over {MAX_MODULE} lines (split them): {over}"


def test_no_class_over_500_lines():
    over = []
    for f in our_python_files():
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS:
                over.append((f.relative_to(REPO).as_posix(), node.name, node.end_lineno - node.lineno + 1))
    assert over == [], f"classes over {MAX_CLASS} lines (split them): {over}"
