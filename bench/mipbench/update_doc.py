"""Puts the output of a full `make bench` into docs/benchmarks.md (between the bench markers).

    make -s bench > build/bench/full-run.txt && .venv/bin/python -m mipbench.update_doc build/bench/full-run.txt
"""
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "benchmarks.md"
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"


def main(argv):
    if len(argv) != 1:
        sys.exit("usage: python -m mipbench.update_doc OUTPUT_OF_MAKE_BENCH")
    try:
        out = Path(argv[0]).read_text().strip()
    except OSError as e:
        sys.exit(f"mipbench.update_doc: error: {argv[0]}: {e.strerror}")
    if "quick run" in out or "bench: full run" not in out:
        sys.exit("mipbench.update_doc: error: not the output of a full `make bench` run")
    doc = DOC.read_text()
    if BEGIN not in doc or END not in doc:
        sys.exit(f"mipbench.update_doc: error: {DOC} lacks the {BEGIN} / {END} markers")
    head, rest = doc.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOC.write_text(f"{head}{BEGIN}\n```text\n{out}\n```\n{END}{tail}")


if __name__ == "__main__":
    main(sys.argv[1:])
