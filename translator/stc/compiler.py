"""Front end driver: parse every file, then check them together."""
from . import parser
from . import syntax as S
from .check import Checker
from .semantics import SEMANTICS
from .semantics import dialect as rules


def dialect_of(fname, dialect=None):
    """The dialect of a file: the one given, else "scl" for *.scl, "twincat" / "codesys" for
    FILE.twincat.st / FILE.codesys.st, else "st"."""
    if dialect:
        return dialect
    if fname.lower().endswith(".scl"):
        return "scl"
    from .vendor_in import dialect_of_name
    return dialect_of_name(fname) or "st"


def compile_files(texts, diags, semantics="matiec", strict_iec=False, dialect=None):
    """texts: [(filename, text, is_library)]. Returns a Project (valid only without errors).
    semantics: "matiec" (reproduce upstream matiec's run-time values, the default), "openplc"
    (the matiec fork OpenPLC v3 ships) or "iec" (IEC 61131-3 values); portability warnings go
    to diags.warnings in every mode. dialect: "st", "scl" (TIA Portal SCL), "twincat",
    "codesys" or None (by each file's name, dialect_of)."""
    if semantics not in SEMANTICS:
        raise ValueError(f"semantics must be one of {', '.join(SEMANTICS)}, not {semantics!r}")
    parsed = []
    for fname, text, lib in texts:
        nodes = parser.parse(text, fname, diags, dialect_of(fname, dialect))
        if nodes is None:
            continue
        if lib:
            nodes = [n for n in nodes if not isinstance(n, S.Configuration)]
        parsed.append((fname, nodes))
    if diags:
        return None
    checker = Checker(diags, semantics, strict_iec)
    checker.dialects = {f: rules(dialect_of(f, dialect), semantics) for f, _t, _l in texts}
    if any(d.arrays_named_by_shape for d in checker.dialects.values()):
        from .scl_in import name_arrays
        name_arrays(parsed)
    return checker.run(parsed)
