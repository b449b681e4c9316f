"""The vendor wiring pages include the glue files as they ship (issue 36): a fenced block
with `file=PATH` in its info string must equal the file, byte for byte, so the page cannot
drift from what CI runs."""
import re

import pytest

from docs_helpers import REPO

BLOCK = re.compile(r"^```[\w-]+(?: [\w-]+)* file=(\S+)[ \t]*\n(.*?)^```", re.S | re.M)
PAGES = sorted((REPO / "docs").glob("wiring-*.md"))


def _blocks():
    out = []
    for page in PAGES:
        for m in BLOCK.finditer(page.read_text()):
            out.append(pytest.param(page, m.group(1), m.group(2),
                                    id=f"{page.name}:{m.group(1)}"))
    return out


@pytest.mark.parametrize("path", ["dist/glue/twincat/MIP_TcModbusIo.twincat.st",
                                  "dist/glue/codesys/MIP_CdsModbusIo.codesys.st",
                                  "dist/glue/s7/MIP_S7ModbusIo.scl"])
def test_each_family_page_includes_its_glue(path):
    assert any(p.values[1] == path for p in _blocks()), f"no wiring page includes {path}"


@pytest.mark.parametrize("page,path,text", _blocks())
def test_an_included_file_is_the_file(page, path, text):
    assert (REPO / path).is_file(), f"{page.name}: {path} does not exist"
    assert text == (REPO / path).read_text(), f"{page.name}: the copy of {path} differs from the file"
