"""The table of stc's diagnostics: problems.csv, one row a problem (after IronPLC's
problem-codes.csv). Every error and warning stc reports carries its code, printed at the end of
the line (`file:3:6: error: ... [S0412]`); `stc --explain CODE` prints the row.

Codes: P (reading the text: the parser, the SCL and TwinCAT / CODESYS front ends), G (the SCL
generator, stc.scl_out), S (the
checker's errors, S0xxx-S7xxx by the part of stc/check/ that reports it), W (portability
warnings). Columns: code, severity (error / warning), title, message (the text stc prints, with
… where it names the construct), example (a file of tests/translator/ that stc reports it for;
empty where only a test's inline program, or none yet, does). tests/translator/test_stc_problems.py
holds the table, the call sites and the examples to each other."""
import csv
from functools import lru_cache
from pathlib import Path
from typing import NamedTuple

TABLE = Path(__file__).with_name("problems.csv")


class Problem(NamedTuple):
    code: str
    severity: str
    title: str
    message: str
    example: str


@lru_cache(maxsize=None)
def problems():
    """{code: Problem}, in the table's order."""
    with open(TABLE, encoding="utf-8", newline="") as f:
        return {r["code"]: Problem(**r) for r in csv.DictReader(f)}


def explain(code):
    """The lines `stc --explain CODE` prints, or None for an unknown code."""
    p = problems().get(code.strip().upper())
    if p is None:
        return None
    lines = [f"{p.code} ({p.severity}): {p.title}", f"  {p.message}"]
    if p.example:
        lines.append(f"  example: tests/translator/{p.example}")
    return lines
