"""blark (SLAC's TwinCAT 3 structured-text parser, PyPI, pinned in requirements.txt) on the
TwinCAT glue files, and on st_lib/ as the baseline: 0 syntax errors (issue 36 item 5).

blark's grammar takes one type per TYPE ... END_TYPE block (a TwinCAT DUT holds one type);
IEC 61131-3 (2nd ed., Annex B.1.3.3, data_type_declaration) allows several, and st_lib's type
files have several. test_one_type_per_block_is_blark_limit shows it on a minimal file; the files
are therefore parsed with each multi-type block split into one block per type, which is what the
import steps of docs/wiring-twincat.md and wiring-codesys.md tell an integrator to do (one DUT
per type). blark is a parser only: it checks syntax, not names or types (IronPLC does those,
test_indep_ironplc.py)."""
import re

import blark.parse as blark_parse
import pytest
from indep_files import need_glue, st_lib_files

COMMENT = re.compile(r"\(\*.*?\*\)|//[^\n]*", re.S)


def split_types(text):
    """The text with every TYPE block of several declarations written as one block per
    declaration (same line count: each new END_TYPE/TYPE pair goes on the line of the `;`)."""
    out = []
    pos = 0
    for m in re.finditer(r"^TYPE\b(.*?)^END_TYPE\b", text, re.S | re.M):
        body = m.group(1)
        # top-level `;` ends a declaration; comments and STRUCT ... END_STRUCT do not count
        masked = COMMENT.sub(lambda c: " " * len(c.group()), body)
        ends, depth = [], 0
        for t in re.finditer(r"\bEND_STRUCT\b|\bSTRUCT\b|;", masked, re.I):
            word = t.group().upper()
            if word == "STRUCT":
                depth += 1
            elif word == "END_STRUCT":
                depth -= 1
            elif depth == 0:
                ends.append(t.end())
        new_body, last = [], 0
        for i, e in enumerate(ends):
            new_body.append(body[last:e])
            if i < len(ends) - 1 and masked[e:].strip():
                new_body.append(" END_TYPE TYPE")
            last = e
        new_body.append(body[last:])
        out.append(text[pos:m.start(1)] + "".join(new_body))
        pos = m.end(1)
    out.append(text[pos:])
    return "".join(out)


def syntax_errors(text, name):
    """[file:line:col: message] of blark on one plain structured-text source."""
    r = blark_parse.parse_source_code(text, fn=name)
    if r.exception is None:
        return []
    e = r.exception
    first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return [f"{name}:{getattr(e, 'line', '?')}:{getattr(e, 'column', '?')}: {first}"]


def file_errors(path):
    if path.suffix == ".st":
        return syntax_errors(split_types(path.read_text(encoding="utf-8")), str(path))
    # TwinCAT's XML objects (.TcPOU, .TcDUT, .TcGVL): blark reads their declaration and
    # implementation parts itself
    out = []
    for r in blark_parse.parse(path):
        if r.exception is not None:
            e = r.exception
            out.append(f"{path}:{getattr(e, 'line', '?')}:{getattr(e, 'column', '?')}: "
                       f"{str(e).strip().splitlines()[0]}")
    return out


def test_one_type_per_block_is_blark_limit():
    two = "TYPE\n  A_T : ARRAY[0..1] OF WORD;\n  B_T : ARRAY[0..1] OF WORD;\nEND_TYPE\n"
    errs = syntax_errors(two, "two.st")
    assert len(errs) == 1 and errs[0].startswith("two.st:3:3:"), errs
    split = split_types(two)
    assert split.count("END_TYPE") == 2 and split.count("\n") == two.count("\n")
    assert syntax_errors(split, "split.st") == []


def test_split_keeps_structs_and_comments():
    text = ("TYPE\n  S_T : STRUCT\n    a : WORD; (* x; y *)\n    b : WORD;\n  END_STRUCT;\n"
            "  (* next; *)\n  E_T : (E_A, E_B);\nEND_TYPE\n")
    split = split_types(text)
    assert split.count("END_TYPE") == 2, split
    assert syntax_errors(split, "s.st") == []
    assert syntax_errors(text, "s.st") != []


def test_twincat_glue_has_no_blark_error():
    files = need_glue("twincat")
    errs = [e for f in files for e in file_errors(f)]
    assert errs == [], "\n".join(errs)


@pytest.mark.slow  # Earley parsing of the whole library: about 30 s
@pytest.mark.parametrize("library", ["core", "chain"])
def test_st_lib_has_no_blark_error(library):
    """The baseline: all of st_lib parses, each library; only the type files need the
    one-type-per-block split (the rest parse as they are)."""
    errs = []
    for f in st_lib_files((library,)):
        text = f.read_text(encoding="utf-8")
        if syntax_errors(text, str(f)):
            errs += syntax_errors(split_types(text), str(f))
    assert errs == [], "\n".join(errs)
