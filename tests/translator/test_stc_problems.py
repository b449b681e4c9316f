"""Every diagnostic of stc has a code in one table, stc/problems.csv (issue 45, after IronPLC's
problem-codes.csv): each code a call site uses is in the table and each row is used, the
table's message is the text the call site prints, the code ends the printed line, and a row's
example file makes stc report that code."""
import ast
import pathlib
import re
import subprocess
import sys

import pytest

import stc
from stc import scl_out
from stc.compiler import compile_files
from stc.diag import Diagnostics
from stc.problems import problems

STC = pathlib.Path(stc.__file__).parent
HERE = pathlib.Path(__file__).parent
CODE = re.compile(r"^[PGSW]\d{4}$")


def _template(n):
    """The text of a message expression, … for each {placeholder}; None when not literal."""
    if isinstance(n, ast.Constant) and isinstance(n.value, str):
        return n.value
    if isinstance(n, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "…" for v in n.values)
    if isinstance(n, ast.BinOp) and isinstance(n.op, ast.Add):
        a, b = _template(n.left), _template(n.right)
        return None if a is None or b is None else a + b
    if isinstance(n, ast.IfExp):
        a, b = _template(n.body), _template(n.orelse)
        return None if a is None or b is None else a + " / " + b
    return None


def _sites():
    """(file:line, code, message template) of every call that passes a code string."""
    out = []
    for f in sorted(STC.rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if not isinstance(node, ast.Call):
                continue
            for i, a in enumerate(node.args):
                if isinstance(a, ast.Constant) and isinstance(a.value, str) and CODE.match(a.value):
                    msg = node.args[i + 1] if i + 1 < len(node.args) else None
                    where = f"{f.relative_to(STC)}:{node.lineno}"
                    out.append((where, a.value, None if msg is None else _template(msg)))
    return out


def test_the_table_and_the_call_sites_agree():
    table = problems()
    sites = _sites()
    used = {code for _w, code, _t in sites}
    assert len(sites) > 250, "the call sites were not found"
    unknown = sorted(f"{w}: {c}" for w, c, _t in sites if c not in table)
    assert not unknown, f"codes used but not in problems.csv: {unknown}"
    unused = sorted(set(table) - used)
    assert not unused, f"rows of problems.csv no call site uses: {unused}"
    for code, p in table.items():
        assert CODE.match(code) and p.severity == ("warning" if code[0] == "W" else "error"), p
        assert p.title and p.message, p


def test_the_table_says_what_the_call_site_prints():
    table = problems()
    # P0101: two sites (the lexer's // and /* */, the comment scanner's /* */), one problem; the
    # sites whose message is made elsewhere (parse_errors._unexpected_message) have no template
    differ = [f"{w}: {c}: the source says {t!r}, the table {table[c].message!r}"
              for w, c, t in _sites() if t is not None and c in table and c != "P0101"
              and t != table[c].message]
    assert not differ, "\n".join(differ)


def test_every_diagnostic_carries_its_code(tmp_path):
    src = tmp_path / "a.st"
    src.write_text("PROGRAM Main\nVAR a : ARRAY[0..2] OF INT; b : ARRAY[0..2] OF INT; END_VAR\n"
                   "a := b;\nEND_PROGRAM\n")
    r = subprocess.run([sys.executable, "-m", "stc.cli", "-o", str(tmp_path / "out"), str(src)],
                       capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stderr.startswith(f"{src}:3:6: error: assignment: arrays can only be assigned"), r.stderr
    assert r.stderr.rstrip().endswith("declare a TYPE and use it on both sides [S0505]"), r.stderr
    r = subprocess.run([sys.executable, "-m", "stc.cli", "--explain", "s0505"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.startswith("S0505 (error): arrays can only be assigned")
    assert "example: tests/translator/reject/array_anonymous_assign.st" in r.stdout
    r = subprocess.run([sys.executable, "-m", "stc.cli", "--explain", "S9999"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "stc: error: --explain S9999: no such code" in r.stderr


def _reported(path):
    d = Diagnostics()
    compile_files([(str(path), path.read_text(), False)], d, "matiec", strict_iec=True)
    return {e[4] for e in d.errors + d.warnings}


def test_each_example_reports_its_code():
    """The example column: the file reports the code (compiled with --strict-iec), and every
    code a corpus file reports has an example (so the column keeps up with the corpora)."""
    table = problems()
    wrong = [f"{c}: {p.example} does not report it" for c, p in table.items()
             if p.example and c not in _reported(HERE / p.example)]
    assert not wrong, wrong
    missing = set()
    for d in ("reject", "scl_reject", "accept", "scl_accept"):
        for f in sorted((HERE / d).iterdir()):
            if f.suffix in (".st", ".scl"):
                missing |= {c for c in _reported(f) if c in table and not table[c].example}
    assert not missing, f"codes a corpus file reports but whose example is empty: {sorted(missing)}"


@pytest.mark.parametrize("sev", ["error", "warning"])
def test_examples_cover_a_share_of_the_table(sev):
    """Not every row has an example file yet (many are triggered by the inline programs of
    test_stc_semantics.py, test_stc_vendor_dialect.py, ...); this keeps the share from falling."""
    rows = [p for p in problems().values() if p.severity == sev]
    share = sum(1 for p in rows if p.example) / len(rows)
    assert share >= {"error": 0.3, "warning": 0.75}[sev], f"{sev}: {share:.0%} have an example"


def test_the_scl_generator_reports_its_codes(tmp_path):
    src = tmp_path / "p.st"
    src.write_text("PROGRAM Main\nVAR x : INT; END_VAR\nx := 1;\nEND_PROGRAM\n")
    with pytest.raises(scl_out.SclError) as e:
        scl_out.generate_files([str(src)], "1.0.0")
    assert str(e.value) == (f"{src}:1:9: error: PROGRAM has no TIA external source form in the "
                            "generator (write an OB) [G0106]")
