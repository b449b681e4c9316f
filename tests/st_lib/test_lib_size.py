"""Issue 46, "Readable blocks": no POU file of st_lib over 400 lines of code (comments aside:
`(* ... *)` removed, blank lines not counted). MIP_Sender was 512 and keeps its window 2 (P27),
its W1 snapshot gate, its record layout, its acknowledgement read and its wait reason in
internal blocks (MIP_Internal_*). The files still over the bound may not grow while they wait
for their split."""
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
LIMIT = 400
# file: its lines of code when this test was written (issue 46 splits them next)
STILL_OVER = {"MIP_Receiver.st": 445, "MIP_SoeReader.st": 485}


def code_lines(text: str) -> int:
    text = re.sub(r"\(\*.*?\*\)", "", text, flags=re.S)
    return sum(1 for line in text.splitlines() if line.strip())


def test_code_lines_ignores_comments_and_blank_lines():
    assert code_lines("(* a\n  header *)\nFUNCTION F : INT\n\n  F := 1; (* one *)\n(* x *)\nEND_FUNCTION\n") == 3


def test_no_block_over_400_lines_of_code():
    sizes = {p.name: code_lines(p.read_text()) for p in sorted((REPO / "st_lib").glob("*.st"))}
    over = {f: n for f, n in sizes.items() if n > STILL_OVER.get(f, LIMIT)}
    assert not over, f"st_lib files over {LIMIT} lines of code (comments aside): {over}; " \
                     "move a part into an internal block (MIP_Internal_..., st_lib/CONVENTIONS.md)"
