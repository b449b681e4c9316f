"""The pages say what happens (issue 39, "Docs and messages that disagree with what happens"):
each test here failed on the text it checks before that text was corrected."""
from __future__ import annotations

import re
import subprocess

import pytest

from docs_helpers import REPO

STC = REPO / ".venv" / "bin" / "stc"
PAGES = sorted([REPO / "README.md"] + [p for p in (REPO / "docs").rglob("*.md")
                                       if "tools" not in p.parts])


def st_blocks(page):
    """(line, text) of the ```st blocks of a page."""
    text = page.read_text()
    return [(text[:m.start()].count("\n") + 1, m.group(1))
            for m in re.finditer(r"^```st[ \t]*\n(.*?)^```", text, re.S | re.M)]


def _complete_pous():
    out = []
    for page in PAGES:
        for line, src in st_blocks(page):
            if re.search(r"^\s*(PROGRAM|FUNCTION_BLOCK)\s+\w+", src, re.M) and \
                    re.search(r"^\s*END_(PROGRAM|FUNCTION_BLOCK)\b", src, re.M):
                out.append(pytest.param(page, line, src,
                                        id=f"{page.relative_to(REPO)}:{line}"))
    return out


@pytest.mark.parametrize("page,line,src", _complete_pous())
def test_a_whole_program_shown_in_the_docs_translates(page, line, src, tmp_path):
    """1. A PROGRAM or FUNCTION_BLOCK shown whole (wiring-openplc.md's outstation) translates
    with stc against st_lib: it once put MIP_Sender and AT %IW100 in one VAR block."""
    f = tmp_path / "shown.st"
    f.write_text(src)
    r = subprocess.run([str(STC), "-I", str(REPO / "st_lib"), "-o", str(tmp_path / "gen"),
                        str(f)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"{page.relative_to(REPO)}:{line}: {r.stderr}"
