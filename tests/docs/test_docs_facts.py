"""Facts the pages state about the code, checked against the code."""
import os
import re

from docs_helpers import REPO


def wait_reasons():
    types = (REPO / "st_lib" / "core" / "MIP_Types.st").read_text()
    types = re.sub(r"\(\*.*?\*\)", "", types, flags=re.S)
    decl = re.search(r"E_MIP_WaitReason\s*:\s*\((.*?)\)", types, re.S)
    assert decl, "st_lib/core/MIP_Types.st: no E_MIP_WaitReason"
    return re.findall(r"\bMIP_WAIT_\w+", decl.group(1))


def test_troubleshooting_explains_every_wait_reason():
    """Every value of E_MIP_WaitReason has its row in troubleshooting.md."""
    values = wait_reasons()
    assert "MIP_WAIT_NONE" in values and "MIP_WAIT_SNAPSHOT" in values
    page = (REPO / "docs" / "troubleshooting.md").read_text()
    rows = set(re.findall(r"^\| `(MIP_WAIT_\w+)` \|", page, re.M))
    assert set(values) - rows == set(), f"docs/troubleshooting.md: no row for {set(values) - rows}"


def _pages():
    from test_docs_commands import PAGES
    return PAGES


def test_inline_make_commands_name_real_targets():
    """Every `make ...` a page names in running text is a target the Makefile has (make -n:
    nothing runs). The command blocks themselves run in test_docs_commands.py."""
    import shlex
    import subprocess
    found = {}
    for page in _pages():
        for m in re.finditer(r"`make ([^`]+)`", page.read_text()):
            cmd = re.split(r"\s(?:&&|\|\|?|;|>>?|<)\s", m.group(1) + " ")[0]
            words = [w for w in shlex.split(cmd) if "=" not in w and not w.startswith("-")]
            for target in words:
                found.setdefault(target, f"{page.relative_to(REPO)}")
    assert {"run", "test", "dist", "docs"} <= set(found)
    bad = []
    for target, where in sorted(found.items()):
        p = subprocess.run(["make", "-n", "-s", "--no-print-directory", target], cwd=REPO,
                           capture_output=True, text=True, timeout=60)
        if p.returncode != 0:
            bad.append(f"{where}: `make {target}`: {p.stderr.strip().splitlines()[-1:]}")
    assert not bad, "\n".join(bad)


def test_command_help_names_no_issue_numbers():
    """User-facing text names no issue numbers: the --help of every command the pages use."""
    import subprocess
    import sys
    venv = REPO / ".venv" / "bin"
    commands = [[str(REPO / "build" / "emulator" / "mip-emulator"), "--help"],
                [str(venv / "mip-cosim"), "--help"], [str(venv / "mip-peer"), "--help"],
                [str(venv / "stc"), "--help"], [str(venv / "plcrt-build"), "--help"]]
    commands += [[sys.executable, str(REPO / f), "--help"]
                 for f in ("plc/demo.py", "plc/gen_programs.py", "plc/openplc_limits.py",
                           "dist/mkdist.py", "docs/tools/mipsim.py", "docs/tools/seqdiag.py")]
    bad = []
    for cmd in commands:
        p = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=60,
                           env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"))
        text = p.stdout + p.stderr
        assert "usage" in text.lower(), f"{cmd}: no usage text:\n{text[-500:]}"
        bad += [f"{' '.join(cmd[-2:])}: {m}" for m in re.findall(r"[^\n]*\bissues? #?\d+[^\n]*", text, re.I)]
    assert not bad, "\n".join(bad)


def test_interop_section_does_not_change_with_the_wall_time():
    """`make interop-matrix` regenerates docs/protocol.md's section 6: only what a rerun
    reproduces goes in, so the tree stays clean after a run with the same results."""
    import copy
    import json
    from mipinterop.docs import table
    doc = json.loads((REPO / "interop" / "results.json").read_text())
    other = copy.deepcopy(doc)
    other["seconds"] = doc.get("seconds", 0) * 3 + 17
    for r in other["results"]:
        r["seconds"] = r.get("seconds", 0) * 3 + 1
    assert table(doc) == table(other)
    assert table(doc) in (REPO / "docs" / "protocol.md").read_text(), \
        "docs/protocol.md: section 6 is not the table of interop/results.json"
