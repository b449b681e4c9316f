"""Helpers of the test kit's tests (kit/, issue 25). Quick tests run mipkit from kit/
(PYTHONPATH) with the repository's venv; the slow ones install it into a fresh venv the
documented way."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
KIT = REPO / "kit"
EXAMPLE = KIT / "example"
BUG = "  IF udiN = 7 THEN aChunk[0] := WORD#17; END_IF;   (* the deliberate bug: record 7 says 17 *)\n"


def break_logger(project: Path):
    """The deliberately broken variant: FieldLogger writes a wrong register into record 7."""
    f = project / "st" / "FieldLogger.st"
    text = f.read_text()
    anchor = "  uChunkLen := 8;\n"
    assert text.count(anchor) == 1, "FieldLogger.st changed: the broken variant needs a new anchor"
    f.write_text(text.replace(anchor, BUG + anchor))


def forget_retain(project: Path):
    """The broken variant of issue 39: the plcrt config without its [retain] section while the
    program runs MIP_Sender with xRetained := TRUE (its snapshots are never counted)."""
    f = project / "plcrt" / "outstation.conf"
    text = f.read_text()
    assert text.count("[retain]") == 1 and text.rstrip().endswith("saved = %IW8"), \
        "outstation.conf changed: the broken variant needs a new anchor"
    f.write_text(text[:text.index("[retain]")])


def copy_example(dst: Path) -> Path:
    shutil.copytree(EXAMPLE, dst, ignore=shutil.ignore_patterns(".venv", "results", "__pycache__"))
    return dst


def kit_env(**extra):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(KIT)] + [p for p in [env.get("PYTHONPATH")] if p])
    env.pop("PYTEST_ADDOPTS", None)
    env.pop("PYTEST_XDIST_WORKER", None)
    env.update(extra)
    return env


def run(cmd, cwd, env=None, timeout=900):
    return subprocess.run([str(c) for c in cmd], cwd=cwd, env=env or kit_env(),
                          capture_output=True, text=True, timeout=timeout)


def kit_pytest(args, cwd, tmp_path):
    """pytest with the kit's plugin in an integrator's project (cwd), quiet, its temporary
    files under tmp_path/bt: the CompletedProcess."""
    return run([sys.executable, "-m", "pytest", "-p", "mipkit.plugin", "-p", "no:cacheprovider", "-q",
                *args, f"--basetemp={tmp_path / 'bt'}"], cwd, kit_env())


def mipkit_cli(args, cwd):
    """mip-kit from kit/ with this venv's Python (what the console script runs)."""
    return run([sys.executable, "-c", "import sys; from mipkit.scenario import main; "
                "sys.exit(main(sys.argv[1:]))", *args], cwd)


def ci_commands(project: Path):
    """The test commands of both CI templates: GitLab's script list and the GitHub step
    'Simulated PLC tests'; they must be the same."""
    gl = (project / ".gitlab-ci.yml").read_text()
    m = re.search(r"^  script:\n((?:    - .*\n)+)", gl, re.M)
    gitlab = [l.strip()[2:] for l in m.group(1).splitlines()] if m else []
    gh = (project / ".github" / "workflows" / "sim-tests.yml").read_text()
    m = re.search(r"- name: Simulated PLC tests\n\s+run: \|\n((?:\s{10}.*\n)+)", gh)
    github = [l.strip() for l in m.group(1).splitlines() if l.strip()] if m else []
    return gitlab, github
