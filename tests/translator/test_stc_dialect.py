"""The dialect rules live in one object (stc.semantics.Dialect, issue 45): the checker and the
code generator ask its named rules and never test a dialect's or a semantics' name, so a new
dialect is one entry in semantics.dialect() and not a hunt through the passes."""
import pathlib
import re

import pytest

import stc
from stc.diag import Diagnostics
from stc.compiler import compile_files
from stc.semantics import SEMANTICS, SOURCE_DIALECTS, Dialect, dialect

STC = pathlib.Path(stc.__file__).parent
# a name of a dialect or semantics inside a string compared in code, e.g. == "openplc",
# in ("twincat", "codesys")
NAME_TEST = re.compile(r"""(==|!=|\bin)\s*\(?\s*["'](%s)["']""" % "|".join(SEMANTICS + SOURCE_DIALECTS))


@pytest.mark.parametrize("part", ["check", "cgen"])
def test_passes_ask_the_rules_not_the_names(part):
    found = []
    for f in sorted((STC / part).glob("*.py")):
        for n, line in enumerate(f.read_text().splitlines(), 1):
            if NAME_TEST.search(line) or "vendor_files" in line or "scl_files" in line:
                found.append(f"{f.name}:{n}: {line.strip()}")
    assert not found, "a pass tests a dialect's name; add a rule to stc.semantics.Dialect:\n" \
        + "\n".join(found)


def test_every_rule_is_used_by_a_pass():
    used = "".join(f.read_text() for part in ("check", "cgen") for f in (STC / part).glob("*.py"))
    used += (STC / "compiler.py").read_text()
    rules = [f for f in Dialect.__dataclass_fields__ if f not in ("source", "semantics")]
    unused = [r for r in rules if f"dialect.{r}" not in used and f"d.{r}" not in used]
    assert not unused, f"rules no pass asks: {unused}"


def test_the_rules_of_each_dialect():
    st, tc, scl = dialect("st"), dialect("twincat"), dialect("scl")
    assert not st.pointers and tc.pointers and dialect("codesys").pointers and not scl.pointers
    assert scl.arrays_named_by_shape and not st.arrays_named_by_shape
    assert dialect("st", "iec").time_as_pair is False and st.time_as_pair
    assert dialect("st", "openplc").fork and not dialect("st", "openplc").for_matiec_upstream
    assert st.for_matiec_upstream
    assert dialect("codesys", "iec") is dialect("codesys", "iec")      # one shared object
    with pytest.raises(ValueError, match="dialect must be one of st, scl, twincat, codesys"):
        dialect("beremiz")


def test_a_files_dialect_decides_its_rules_in_a_mixed_build():
    """The same construct is read in a .twincat.st file and refused in a .st file of one build."""
    text = "FUNCTION_BLOCK {n}\nVAR p : POINTER TO BYTE; END_VAR\np := p;\nEND_FUNCTION_BLOCK\n"
    d = Diagnostics()
    compile_files([("a.twincat.st", text.format(n="A"), False), ("b.st", text.format(n="B"), False)], d)
    assert {e[0] for e in d.errors} == {"b.st"}, d.errors
    assert d.errors[0][1:3] == (2, 17) and "POINTER TO is not portable" in d.errors[0][3]
