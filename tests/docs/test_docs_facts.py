"""Facts the pages state about the code, checked against the code."""
import re

from docs_helpers import REPO


def wait_reasons():
    types = (REPO / "st_lib" / "MIP_Types.st").read_text()
    types = re.sub(r"\(\*.*?\*\)", "", types, flags=re.S)
    decl = re.search(r"E_MIP_WaitReason\s*:\s*\((.*?)\)", types, re.S)
    assert decl, "st_lib/MIP_Types.st: no E_MIP_WaitReason"
    return re.findall(r"\bMIP_WAIT_\w+", decl.group(1))


def test_troubleshooting_explains_every_wait_reason():
    """Every value of E_MIP_WaitReason has its row in troubleshooting.md."""
    values = wait_reasons()
    assert "MIP_WAIT_NONE" in values and "MIP_WAIT_SNAPSHOT" in values
    page = (REPO / "docs" / "troubleshooting.md").read_text()
    rows = set(re.findall(r"^\| `(MIP_WAIT_\w+)` \|", page, re.M))
    assert set(values) - rows == set(), f"docs/troubleshooting.md: no row for {set(values) - rows}"
