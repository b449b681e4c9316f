"""Issue 25's "done when": the example integrator project, copied to a directory outside the
checkout, gets the kit installed the documented way into a fresh venv (the commands of its CI
templates: `python3 -m venv .venv`, `.venv/bin/pip install "$MIP_KIT"` with MIP_KIT = this
checkout's kit/), runs its tests and its scenario (10,000 records over the realistic radio):
green; then the deliberately broken variant: red, naming record 7, with the diagram.

pip fetches lark, pymodbus, pytest and the build backend from the package index (or the pip
configuration's find-links): the documented install is what is tested, so it is not faked
offline here; without a reachable index the test is skipped and says so. The wheel itself is
built offline in the quick tier (test_kit_quick.py)."""
import os
import re
import subprocess
import xml.etree.ElementTree as ET

import pytest

from kit_helpers import KIT, REPO, break_logger, ci_commands, copy_example


def outside_env(kit, base):
    """The environment of an integrator's machine: MIP_KIT (what the project's CI installs: the
    kit's folder or its archive), nothing of this checkout, the build cache under base."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTEST_ADDOPTS", "PYTEST_XDIST_WORKER",
                        "PLCRT_CACHE", "PLCRT_COMPILER", "PLCRT_SEMANTICS")}
    # the venv of this checkout must not leak in: only the system's python3 on PATH
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if not p.startswith(str(REPO)))
    env["MIP_KIT"] = str(kit)
    env["XDG_CACHE_HOME"] = str(base / "cache")      # the installed harness's build cache
    return env

pytestmark = pytest.mark.slow


NO_INDEX = ("Failed to establish a new connection", "Temporary failure in name resolution",
            "Network is unreachable", "No matching distribution found for lark")


def sh(cmd, cwd, env, timeout=900):
    r = subprocess.run(["bash", "-c", cmd], cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=timeout)
    if r.returncode != 0 and "pip install" in cmd and any(s in r.stderr + r.stdout for s in NO_INDEX):
        pytest.skip(f"the documented install needs the package index for lark, pymodbus and "
                    f"pytest, and it is not reachable: {r.stderr.strip().splitlines()[-1]}")
    return r


def test_example_project_installs_and_runs_outside_the_checkout(tmp_path_factory):
    base = tmp_path_factory.mktemp("integrator")
    assert REPO not in base.parents, "the project must live outside the checkout"
    project = copy_example(base / "project")
    env = outside_env(KIT, base)
    gitlab, github = ci_commands(project)
    assert gitlab == github and len(gitlab) == 4
    for cmd in gitlab:
        r = sh(cmd, project, env)
        assert r.returncode == 0, f"{cmd}:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    # what CI uploads (results/): the JUnit files, no build products, no trace of a passing run
    files = [p for p in (project / "results").rglob("*") if p.is_file()]
    assert sum(p.stat().st_size for p in files) < 1_000_000, files
    assert sorted(p.name for p in files) == ["pytest.xml", "scenario.xml"], files
    scen = ET.parse(project / "results" / "scenario.xml").getroot()
    assert scen.get("failures") == "0" and scen.get("tests") == "5"
    suite = ET.parse(project / "results" / "pytest.xml").getroot().find("testsuite")
    assert suite.get("failures") == "0" and int(suite.get("tests")) >= 2
    # the commissioning tool comes with the kit (issue 48)
    r = sh(".venv/bin/mip-probe --help", project, env)
    assert r.returncode == 0 and r.stdout.startswith("usage: mip-probe"), r.stdout + r.stderr
    # nothing of the checkout on the installed packages' path
    r = sh(".venv/bin/python -c 'import stc, plcharness.build as b, mipcosim.sim as s, mippeer, mipkit;"
           "print(stc.__file__, b.RUNTIME_DIR, s.LIBDIR, mipkit.__file__)'", project, env)
    assert r.returncode == 0 and str(REPO) not in r.stdout, r.stdout + r.stderr

    # the deliberately broken variant: red, naming the record, with the diagram
    break_logger(project)
    r = sh(".venv/bin/pytest -q --junitxml=results/broken.xml", project, env)
    out = r.stdout + r.stderr
    assert r.returncode == 1, out
    assert "record 7: got [17, 0, 21, 28, 35, 42, 49, 56], want [7, 0, 21, 28, 35, 42, 49, 56]" in out
    assert re.search(r"^mip-kit: fault: record 7 \(transfer 1, record 7 on the radio\): central "
                     r"accepted it at \d+\.\d{3} s$", out, re.M), out
    svg = re.search(r"^mip-kit: sequence diagram .*: (\S+sequence-diagram\.svg)$", out, re.M)
    assert svg and open(svg.group(1)).read().startswith("<svg"), out
    assert svg.group(1).startswith(str(project / "results" / "mip-kit")), out
    r = sh(".venv/bin/mip-kit scenarios/readout.toml --junit results/broken-scenario.xml", project, env)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "FAIL numbered records at central: record 7: its registers say record 17" in r.stdout
    assert "mip-kit: fault: record 7 (transfer 1, record 7 on the radio)" in r.stdout
    props = {p.get("name"): p.get("value")
             for p in ET.parse(project / "results" / "broken-scenario.xml").getroot().iter("property")}
    assert open(props["mip_diagram"]).read().startswith("<svg")


def test_kit_installs_from_its_source_archive(tmp_path_factory):
    """The other documented way: the kit's source archive (`make kit-dist`), installed with one
    pip command into a fresh venv outside the checkout, runs the example's tests."""
    import sys
    base = tmp_path_factory.mktemp("archive")
    r = subprocess.run([sys.executable, "-c", "import sys; from setuptools import build_meta as b;"
                        "print(b.build_sdist(sys.argv[1]))", str(base)], cwd=KIT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    archive = base / r.stdout.strip().splitlines()[-1]
    assert archive.name.startswith("mip_logger_kit-") and archive.suffixes[-2:] == [".tar", ".gz"]
    project = copy_example(base / "project")
    env = outside_env(archive, base)
    gitlab, _ = ci_commands(project)
    for cmd in gitlab[:3]:                    # venv, install, the project's tests
        r = sh(cmd, project, env)
        assert r.returncode == 0, f"{cmd}:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    # every test of the project ran and passed (the outstation's and the chain's)
    n = sum(f.read_text().count("\ndef test_") for f in (project / "tests").glob("test_*.py"))
    assert n >= 5 and f"{n} passed" in r.stdout, r.stdout
