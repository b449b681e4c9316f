"""The enum numbers Python uses come from st_lib/core/MIP_Types.st through one reader
(mipcosim.programs.st_enums): it agrees with the documentation's reader (docs/tools/stdecl.py,
behind the 'as integer' column of docs/blocks.md) and refuses what it cannot number."""
import re
from pathlib import Path

import pytest

from mipcosim.programs import ERRORS, EnumError, enum_values, st_enums

REPO = Path(__file__).resolve().parents[2]


def test_reader_agrees_with_the_documentation_reader():
    from mipdocs import stdecl
    unit = stdecl.parse_file(str(REPO / "st_lib" / "core" / "MIP_Types.st"))
    documented = {t.name: [v for v, _ in t.values] for t in unit.types if t.kind == "enum"}
    assert st_enums() == documented
    assert len(documented) >= 4


def test_numbers_are_the_positions():
    err = enum_values("E_MIP_Error")
    assert err["MIP_ERR_NONE"] == 0
    assert ERRORS[err["MIP_ERR_PEER_OUT_OF_STEP"]] == "PEER_OUT_OF_STEP"


def test_comments_and_layout_do_not_matter(tmp_path):
    st = tmp_path / "T.st"
    st.write_text("TYPE\n  (* a ( comment ); *)\n  E_A : (A_X,   (* first, (with) parens *)\n"
                  "    A_Y\n  , A_Z);\n  T_ARR : ARRAY[0..3] OF WORD;\n  E_B : (B_0);\nEND_TYPE\n")
    assert st_enums(st) == {"E_A": ["A_X", "A_Y", "A_Z"], "E_B": ["B_0"]}
    assert enum_values("E_A", st)["A_Z"] == 2


def test_explicit_numbers_and_unknown_types_are_refused(tmp_path):
    st = tmp_path / "U.st"
    st.write_text("TYPE\n  E_A : (A_X := 1, A_Y := 5);\nEND_TYPE\n")
    with pytest.raises(EnumError, match="explicit numbers"):
        st_enums(st)
    with pytest.raises(EnumError, match="no enumerated type E_NOPE"):
        enum_values("E_NOPE")


def test_every_enum_value_is_used():
    # an unused value is dead and holds the numbers after it hostage (issue 29: MIP_SND_RESET);
    # while the version is 0.x it goes, with a CHANGELOG entry
    code = " ".join(re.sub(r"\(\*.*?\*\)", " ", p.read_text(), flags=re.S)
                    for p in sorted((REPO / "st_lib").glob("*/*.st")) if p.name != "MIP_Types.st")
    used = {w.upper() for w in re.findall(r"\bMIP_\w+", code, re.I)}   # ST is case-blind
    unused = [v for vals in st_enums().values() for v in vals if v.upper() not in used]
    assert unused == []
