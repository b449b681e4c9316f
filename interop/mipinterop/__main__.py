"""python -m mipinterop: run the interop matrix, or write its table into docs/protocol.md.

  python -m mipinterop --out results.json [--cells KEY,...] [--realtime]
  python -m mipinterop --write-docs results.json

By default every cell runs in the co-simulation kernel, in virtual time (deterministic by seed);
--realtime runs the soft-PLC executable and the mip-peer process over mip-emulator instead.
"""
import argparse
import json
import sys
import tempfile
from pathlib import Path

from . import docs
from .matrix import Cell, Config, MatrixError, all_cells, run_matrix


class _Parser(argparse.ArgumentParser):
    def error(self, message):          # one line, not usage + message
        self.exit(2, f"{self.prog}: error: {message}\n")


def main(argv=None):
    p = _Parser(prog="mipinterop", description=__doc__.splitlines()[0])
    p.add_argument("--out", help="run the matrix and write its results (JSON) here")
    p.add_argument("--cells", help="only these cells: ours/reading/fault/layout/mode, comma-separated")
    p.add_argument("--drive", choices=["spontaneous", "polled"], default="spontaneous",
                   help="drive of both sides (the CI matrix: spontaneous)")
    p.add_argument("--realtime", action="store_true",
                   help="processes over mip-emulator on 127.0.0.1 in real time instead of the "
                        "co-simulation kernel (virtual time)")
    p.add_argument("--workdir", help="logs of every cell (default: a temporary directory)")
    p.add_argument("--write-docs", metavar="RESULTS",
                   help="write the table of this results file into docs/protocol.md")
    a = p.parse_args(argv)
    if bool(a.out) == bool(a.write_docs):
        p.error("give either --out (run) or --write-docs RESULTS")
    try:
        if a.write_docs:
            try:
                doc = json.loads(Path(a.write_docs).read_text())
            except (OSError, json.JSONDecodeError) as e:
                print(f"mipinterop: error: {a.write_docs}: {e}", file=sys.stderr)
                return 1
            docs.write(doc)
            print(f"mipinterop: wrote the table of {len(doc['results'])} cells into {docs.DOC}")
            return 0
        try:
            cells = [Cell.parse(k) for k in a.cells.split(",")] if a.cells else all_cells()
        except ValueError as e:
            p.error(str(e))

        def progress(i, n, r):
            took = f"{r.seconds:g} s" if r.virtual_s is None else \
                f"{r.virtual_s:g} s virtual, {r.seconds:g} s"
            print(f"[{i}/{n}] {r.cell}: {r.text} ({took})"
                  f"{'' if r.passed else '  <-- FAIL'}", flush=True)

        with tempfile.TemporaryDirectory(prefix="mipinterop-") as tmp:
            work = Path(a.workdir) if a.workdir else Path(tmp)
            doc = run_matrix(cells, Config(drive=a.drive), work, progress, realtime=a.realtime)
        Path(a.out).write_text(json.dumps(doc, indent=1) + "\n")
        failed = [r for r in doc["results"] if not r["passed"]]
        virtual = f" ({doc['virtual_seconds']:g} s virtual)" if "virtual_seconds" in doc else ""
        print(f"mipinterop: {len(cells) - len(failed)} of {len(cells)} cells pass "
              f"in {doc['seconds']:g} s{virtual}; results in {a.out}")
        return 1 if failed else 0
    except (MatrixError, docs.DocsError) as e:
        print(f"mipinterop: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
