"""The import contracts between our packages (.importlinter, docs/dev/architecture.md): they hold
on the tree, every installed package of ours is under them, and they fail, naming the import,
on an upward import or a cycle added to a copy of a package (the tree is not touched)."""
import configparser
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from mipdocs import importgraph

REPO = Path(__file__).resolve().parents[2]
CONTRACTS = REPO / ".importlinter"
LINT_IMPORTS = Path(sys.executable).parent / "lint-imports"


def lint_imports(cwd, pythonpath=()):
    # mipkit from kit/ as pytest.ini has it; a copy in pythonpath comes first and hides the
    # installed package of the same name; COLUMNS: no line of the report wrapped
    env = dict(os.environ, COLUMNS="200",
               PYTHONPATH=os.pathsep.join([*map(str, pythonpath), str(REPO / "kit")]))
    return subprocess.run([str(LINT_IMPORTS), "--no-cache", "--config", str(cwd / ".importlinter")],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def broken_part(out):
    return out[out.find("Broken contracts"):] if "Broken contracts" in out else out


def test_the_import_contracts_hold():
    r = lint_imports(REPO)
    if r.returncode != 0:
        pytest.fail("lint-imports (.importlinter): " + broken_part(r.stdout) + r.stderr, pytrace=False)
    assert "Contracts: 3 kept, 0 broken." in r.stdout, r.stdout


def test_every_installed_package_of_ours_is_under_the_contracts():
    """A package a part adds (its pyproject.toml) must be placed in the layers too."""
    cp = configparser.ConfigParser()
    cp.read(CONTRACTS)
    roots = set(cp.get("importlinter", "root_packages").split())
    layered = {p.strip() for line in cp.get("importlinter:contract:layers", "layers").splitlines()
               for p in line.split("|") if p.strip()}
    installed = set()
    for pyproject in REPO.glob("**/pyproject.toml"):
        if {".venv", "build"} & set(pyproject.relative_to(REPO).parts):
            continue
        setuptools = tomllib.loads(pyproject.read_text()).get("tool", {}).get("setuptools", {})
        packages = setuptools.get("packages", [])
        if isinstance(packages, dict):            # [tool.setuptools.packages.find] include = ["x*"]
            packages = [p.rstrip("*") for p in packages.get("find", {}).get("include", [])]
        installed |= set(packages)
    assert installed >= {"stc", "plcharness", "mipcosim", "mipkit"}, installed   # the reader works
    assert installed - roots == set(), "packages not in root_packages of .importlinter"
    assert installed - layered == set(), "packages in no layer of .importlinter"


def copy_of(pkg, tmp_path):
    """tmp_path/pkg: a copy of our installed package, and the contracts beside it."""
    src = Path(list(importlib.util.find_spec(pkg).submodule_search_locations)[0])
    shutil.copytree(src, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(CONTRACTS, tmp_path / ".importlinter")
    return tmp_path / pkg


def test_an_upward_import_breaks_the_layers_and_names_the_import(tmp_path):
    # the commissioning probe (bottom layer, pure Python) importing the kit (a top layer)
    (copy_of("mipprobe", tmp_path) / "upward.py").write_text(
        '"""Deliberately upward."""\n\nfrom mipkit import report\n')
    r = lint_imports(tmp_path, [tmp_path])
    assert r.returncode == 1, r.stdout + r.stderr
    out = broken_part(r.stdout)
    assert "mipprobe is not allowed to import mipkit:" in out, out
    assert "- mipprobe.upward -> mipkit.report (l.3)" in out, out


def test_a_cycle_inside_a_package_breaks_the_contract_and_names_the_import(tmp_path):
    pkg = copy_of("mipprobe", tmp_path)
    (pkg / "cycle_a.py").write_text("from . import cycle_b\n")
    (pkg / "cycle_b.py").write_text("from . import cycle_a\n")
    r = lint_imports(tmp_path, [tmp_path])
    assert r.returncode == 1, r.stdout + r.stderr
    out = broken_part(r.stdout)
    assert "No cycles are allowed in mipprobe." in out, out
    assert re.search(r"- \.cycle_[ab] -> \.cycle_[ab] \(1 import\)", out), out
    # and the graph tool names the modules of the cycle
    g = subprocess.run([sys.executable, "-m", "mipdocs.importgraph", "--cycles"], cwd=tmp_path,
                       env=dict(os.environ, PYTHONPATH=f"{tmp_path}{os.pathsep}{REPO / 'kit'}"),
                       capture_output=True, text=True, timeout=300)
    assert g.returncode == 1, g.stdout + g.stderr
    assert "cycle: mipprobe.cycle_a <-> mipprobe.cycle_b\n" in g.stdout, g.stdout


class FakeGraph:
    def __init__(self, edges):
        self.edges = edges
        self.modules = set(edges) | {b for bs in edges.values() for b in bs}

    def find_modules_directly_imported_by(self, m):
        return set(self.edges.get(m, ()))


def test_module_cycles_finds_each_circle_once():
    g = FakeGraph({"p.a": ["p.b"], "p.b": ["p.c"], "p.c": ["p.a", "p.d"], "p.d": ["p.e"],
                   "p.e": [], "q.x": ["q.x"], "q.y": ["q.z"], "q.z": ["q.y", "p.a"]})
    assert importgraph.module_cycles(g) == [["p.a", "p.b", "p.c"], ["q.x"], ["q.y", "q.z"]]
    assert importgraph.module_cycles(FakeGraph({"p.a": ["p.b"], "p.b": []})) == []


def test_no_import_cycle_between_our_modules():
    graph = importgraph.build_graph(importgraph.read_contracts()[0])
    cycles = importgraph.module_cycles(graph)
    assert cycles == [], "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)
    assert len(graph.modules) > 100       # the graph holds our packages
