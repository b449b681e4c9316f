"""The block reference, one part per library (docs/blocks.md: the core, docs/blocks-chain.md:
the chain), is generated from the doc headers in st_lib/<library>/*.st and must be up to date."""
import subprocess
from pathlib import Path

from docs_helpers import PY, REPO, ST_LIB, refused, rel, tool

PARTS = {"core": "blocks.md", "chain": "blocks-chain.md"}


def test_blocks_md_is_up_to_date(tmp_path):
    r = subprocess.run([PY, str(REPO / "dist" / "mkdist.py"), "--reference", str(tmp_path)],
                       cwd=REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    for lib, name in PARTS.items():
        text = (tmp_path / name).read_text()
        assert text.startswith(f"# Block reference: the {lib} library\n")
        assert text == (REPO / "docs" / name).read_text(), \
            f"docs/{name} is stale: run `make docs-blocks` and commit it"


def test_each_part_has_its_librarys_blocks_only():
    for lib, name in PARTS.items():
        text = (REPO / "docs" / name).read_text()
        for f in ST_LIB:
            for line in Path(f).read_text().splitlines():
                if line.startswith(("FUNCTION_BLOCK ", "FUNCTION ")):
                    assert (f"## {line.split()[1]}\n" in text) == (f"/st_lib/{lib}/" in f), (name, f)


def test_every_block_and_error_is_in_the_reference():
    text = "".join((REPO / "docs" / n).read_text() for n in PARTS.values())
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
    r = refused("blockref", "--check", st)
    assert "FB_X.xB (in) is not in the header's interface table" in r.stderr
    assert "FB_X.xGone (out)" in r.stderr


def test_syntax_error_is_one_line_with_position(tmp_path):
    st = tmp_path / "bad.st"
    st.write_text("FUNCTION_BLOCK FB_Y\nVAR_INPUT\n  xA BOOL;\nEND_VAR\nEND_FUNCTION_BLOCK\n")
    r = refused("blockref", "-o", tmp_path / "o.md", st)
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
    r = refused("blockref", "--check", st)
    lines = r.stderr.strip().splitlines()
    assert lines == [f"{st}:13: FB_Z.xB has no trailing comment (the header's meaning: "
                     f"'stops it')",
                     f"{st}:16: FB_Z.xC: the trailing comment differs from the header's "
                     f"meaning column"], r.stderr


def test_sampled_lists_are_generated_from_the_headers():
    """st_lib/README.md and PROTOCOL.md (P26) list which inputs are sampled at which edge: the
    text between the markers is what the headers' 'sampled' column gives."""
    from mipdocs import blockref
    r = tool("blockref", "--sampled", *rel(ST_LIB))
    assert r.returncode == 0, r.stderr
    assert "`MIP_Sender`: at the rising edge of `xExecute`: `uChunkSize`" in r.stdout
    for doc in ("README.md", "PROTOCOL.md"):
        text = (REPO / "st_lib" / doc).read_text()
        a = text.index(blockref.SAMPLED_BEGIN) + len(blockref.SAMPLED_BEGIN)
        b = text.index(blockref.SAMPLED_END)
        assert text[a:b] == "\n" + r.stdout, f"st_lib/{doc} is stale: run `make docs-blocks`"


def test_check_compares_the_sampled_column_with_the_latch(tmp_path):
    """A header that calls a latched input live, or a live input latched, is reported: here
    MIP_Sender's uWindow (copied in the latch) and xAbort (used in the logic)."""
    for f in ST_LIB:
        (tmp_path / Path(f).name).write_text(Path(f).read_text())
    snd = tmp_path / "MIP_Sender.st"
    text = snd.read_text()
    rows = [line for line in text.splitlines() if line.startswith(("  | uWindow ", "  | xAbort "))]
    assert len(rows) == 2
    for row in rows:
        swapped = (row.replace("| rise of xExecute |", "| live             |") if "rise of" in row
                   else row.replace("| live             |", "| rise of xExecute |"))
        assert swapped != row
        text = text.replace(row, swapped)
    snd.write_text(text)
    r = refused("blockref", "--check", *sorted(tmp_path.glob("*.st")))
    line = next(i for i, x in enumerate(text.splitlines(), 1) if x.startswith("FUNCTION_BLOCK"))
    got = r.stderr.strip().splitlines()
    assert f"{snd}:{line}: MIP_Sender.XABORT: the header says sampled 'rise of xExecute', the " \
           f"code: 'live'" in got, r.stderr
    assert f"{snd}:{line}: MIP_Sender.UWINDOW: the header says sampled 'live', the code: " \
           f"'rise of xExecute'" in got, r.stderr
    # the blocks that pass the input on to MIP_Sender inherit its column: reported too
    assert {x.split(": ")[1].split(".")[0] for x in got} == {"MIP_Sender", "MIP_BufferSender",
                                                             "MIP_Link"}
    assert len(got) == 6
