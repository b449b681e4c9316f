"""docs/blocks.md is generated from the doc headers in st_lib/*.st and must be up to date."""
from pathlib import Path

from docs_helpers import REPO, ST_LIB, rel, tool


def test_blocks_md_is_up_to_date(tmp_path):
    out = tmp_path / "blocks.md"
    r = tool("blockref", "-o", out, *rel(ST_LIB))
    assert r.returncode == 0, r.stderr
    assert out.read_text() == (REPO / "docs" / "blocks.md").read_text(), \
        "docs/blocks.md is stale: run `make docs-blocks` and commit it"


def test_every_block_and_error_is_in_the_reference():
    text = (REPO / "docs" / "blocks.md").read_text()
    for f in ST_LIB:
        src = Path(f).read_text()
        for line in src.splitlines():
            if line.startswith("FUNCTION_BLOCK "):
                name = line.split()[1]
                assert f"## {name}\n" in text, name
    for err in ("MIP_ERR_NO_ACK", "MIP_ERR_PEER_RESET", "MIP_ERR_SENDER_RESET"):
        assert f"| `{err}` |" in text


def test_headers_agree_with_declarations():
    """Every input/output of every block is documented in its header and nothing else is."""
    r = tool("blockref", "--check", *rel(ST_LIB))
    assert r.returncode == 0, "header and declaration disagree:\n" + r.stderr


def test_check_finds_an_undocumented_input(tmp_path):
    st = tmp_path / "FB_X.st"
    st.write_text("(*@ block FB_X\n@purpose\n  Test.\n@interface\n"
                  "  | name | dir | type | default | meaning |\n"
                  "  | xA   | in  | BOOL | FALSE   | a |\n*)\n"
                  "FUNCTION_BLOCK FB_X\nVAR_INPUT\n  xA : BOOL;\n  xB : BOOL;\nEND_VAR\n"
                  "VAR_OUTPUT\n  xGone : BOOL;\nEND_VAR\nEND_FUNCTION_BLOCK\n")
    r = tool("blockref", "--check", st)
    assert r.returncode == 1
    assert "FB_X.xB (in) is not in the header's interface table" in r.stderr
    assert "FB_X.xGone (out)" in r.stderr


def test_syntax_error_is_one_line_with_position(tmp_path):
    st = tmp_path / "bad.st"
    st.write_text("FUNCTION_BLOCK FB_Y\nVAR_INPUT\n  xA BOOL;\nEND_VAR\nEND_FUNCTION_BLOCK\n")
    r = tool("blockref", "-o", tmp_path / "o.md", st)
    assert r.returncode == 1
    assert r.stderr.strip() == f"{st}:3:6: error: expected :, found 'BOOL'"
    assert "Traceback" not in r.stderr


def test_check_wants_the_meaning_as_trailing_comment(tmp_path):
    """The IDE shows a declaration's own comment: it must be there and say what the header's
    meaning column says (whitespace aside)."""
    st = tmp_path / "FB_Z.st"
    st.write_text("(*@ block FB_Z\n@purpose\n  Test.\n@interface\n"
                  "  | name | dir | type | default | meaning |\n"
                  "  | xA   | in  | BOOL | FALSE   | starts it |\n"
                  "  | xB   | in  | BOOL | FALSE   | stops it |\n"
                  "  | xC   | out | BOOL |         | done |\n*)\n"
                  "FUNCTION_BLOCK FB_Z\nVAR_INPUT\n  xA : BOOL; (* starts   it *)\n"
                  "  xB : BOOL;\nEND_VAR\nVAR_OUTPUT\n  xC : BOOL; (* finished *)\nEND_VAR\n"
                  "END_FUNCTION_BLOCK\n")
    r = tool("blockref", "--check", st)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert lines == [f"{st}:13: FB_Z.xB has no trailing comment (the header's meaning: "
                     f"'stops it')",
                     f"{st}:16: FB_Z.xC: the trailing comment differs from the header's "
                     f"meaning column"], r.stderr
