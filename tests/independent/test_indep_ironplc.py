"""IronPLC (ironplc/ironplc, an independent IEC 61131-3 compiler) on the TwinCAT and CODESYS
files, in its `twincat` and `codesys` dialects: 0 errors (issue 36 item 5).

Each family is checked as one compilation unit: the portable blocks (st_lib/*/*.st), the glue
files (dist/glue/<family>/**) and declarations of the vendor client blocks the glue calls
(tests/independent/stubs/<family>/: names from the wiring page, no behaviour; a glue file that declares
a block itself, such as a stand-in, replaces the stub of that name).

IronPLC has no library namespaces (`ModbusFB.ClientTCP` is a syntax error in its codesys
dialect, test_namespace_is_ironplc_limit, and so is `Tc2_ModbusSrv.FB_MBReadRegs` in its twincat
dialect), so the glue is checked with the prefixes `ModbusFB.` / `Tc2_ModbusSrv.` dropped. What IronPLC checks: syntax, undeclared names, named inputs a block does not
have, assignment type mismatches (test_ironplc_finds_what_it_checks); it does not flag an unknown
member of an instance (`fb.nothere`), so 0 errors is no proof of that.

Without an ironplcc that has these dialects every test here skips with the reason (how to build
it: docs/wiring-twincat.md, Independent checks)."""
import re
import subprocess

import pytest
from indep_files import REPO, STUBS, ironplcc, need_glue, st_lib_files

ANSI = re.compile(r"\x1b\[[0-9;]*m")
DIALECTS = {"twincat": "twincat", "codesys": "codesys"}
# the library namespaces the glue qualifies the vendor blocks with, which IronPLC cannot parse
NAMESPACES = {"codesys": ("ModbusFB.",), "twincat": ("Tc2_ModbusSrv.",)}
DECL = re.compile(r"^\s*(?:FUNCTION_BLOCK|FUNCTION|PROGRAM)\s+(\w+)", re.M | re.I)


def problems(exe, dialect, files):
    """[(file:line:col, code and message)] of `ironplcc check --dialect D files...`."""
    r = subprocess.run([exe, "check", "--dialect", dialect, *map(str, files)],
                       capture_output=True, text=True, timeout=120)
    out = ANSI.sub("", r.stdout + r.stderr)
    found = re.findall(r"^(error\[\w+\]: [^\n]*)\n\s*\S+ (\S+:\d+:\d+)", out, re.M)
    if r.returncode != 0 and not found:
        found = [("(no location)", out.strip() or f"exit {r.returncode}")]
    return [(where, what) for what, where in found]


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def unit(family, tmp_path):
    """(files of one family's compilation unit, {tmp copy: the glue file it was made from});
    a copy has the namespaces dropped and the same lines."""
    glue = need_glue(family)
    declared = set()
    files = []
    origin = {}
    for g in glue:
        text = g.read_text(encoding="utf-8")
        declared |= {n.upper() for n in DECL.findall(text)}
        for ns in NAMESPACES[family]:
            text = text.replace(ns, "")
        files.append(write(tmp_path, f"glue_{len(files)}_{g.name}", text))
        origin[str(files[-1])] = str(g.relative_to(REPO))
    for s in sorted((STUBS / family).glob("*.st")):
        text = s.read_text(encoding="utf-8")
        # keep only the stub blocks the glue does not declare itself
        parts = re.split(r"(?=^FUNCTION_BLOCK\s)", text, flags=re.M)
        kept = [p for p in parts
                if not (DECL.match(p) and DECL.match(p).group(1).upper() in declared)]
        files.append(write(tmp_path, f"stub_{s.name}", "".join(kept)))
    return [*st_lib_files(), *files], origin


@pytest.mark.parametrize("family", sorted(DIALECTS))
def test_glue_has_no_ironplc_error(family, tmp_path):
    exe = ironplcc()
    files, origin = unit(family, tmp_path)
    found = problems(exe, DIALECTS[family], files)
    for copy, glue in origin.items():
        found = [(w.replace(copy, glue), m) for w, m in found]
    assert found == [], "\n".join(f"{w}: {m}" for w, m in found)


@pytest.mark.parametrize("library", ["core", "chain"])
@pytest.mark.parametrize("dialect", ["twincat", "codesys", "iec61131-3-ed2"])
def test_st_lib_has_no_ironplc_error(dialect, library):
    """The baseline: the portable blocks alone, in both vendor dialects and in strict IEC; each
    library as one unit: the core alone, the chain on the core (issue 46)."""
    exe = ironplcc()
    found = problems(exe, dialect, st_lib_files(("core",) if library == "core" else ("core", "chain")))
    assert found == [], "\n".join(f"{w}: {m}" for w, m in found)


PROBE = """FUNCTION_BLOCK FB_Probe
VAR_INPUT
  a : BOOL; (* an input *)
END_VAR
END_FUNCTION_BLOCK
PROGRAM P_Probe
VAR
  fb : FB_Probe;
  b : BOOL;
  w : WORD;
END_VAR
  fb(zz := TRUE);
  w := b;
  b := xUndeclared;
END_PROGRAM
"""


def test_ironplc_finds_what_it_checks(tmp_path):
    """0 errors means something: the same ironplcc reports each kind of mistake it checks."""
    exe = ironplcc()
    f = write(tmp_path, "probe.st", PROBE)
    found = problems(exe, "twincat", [f])
    codes = sorted(re.match(r"error\[(\w+)\]", m).group(1) for _, m in found)
    where = sorted(w.rsplit(":", 2)[1] for w, _ in found)
    assert len(found) == 3, found
    assert where == ["12", "13", "14"], found
    assert len(set(codes)) == 3, found


def test_vendor_pointer_syntax_needs_the_dialect(tmp_path):
    """The dialects are what make the vendor text pass: POINTER TO / ADR / SIZEOF are errors in
    strict IEC and accepted under twincat and codesys."""
    exe = ironplcc()
    f = write(tmp_path, "ptr.st", "FUNCTION_BLOCK FB_Ptr\nVAR\n  p : POINTER TO WORD;\n"
              "  a : ARRAY[0..3] OF WORD;\n  n : UDINT;\nEND_VAR\n  p := ADR(a);\n"
              "  n := SIZEOF(a);\nEND_FUNCTION_BLOCK\n")
    assert problems(exe, "iec61131-3-ed2", [f]) != []
    assert problems(exe, "twincat", [f]) == []
    assert problems(exe, "codesys", [f]) == []


@pytest.mark.parametrize("dialect,ns,block", [("codesys", "ModbusFB.", "ClientTCP"),
                                               ("twincat", "Tc2_ModbusSrv.", "FB_MBReadRegs")])
def test_namespace_is_ironplc_limit(dialect, ns, block, tmp_path):
    """Why the glue is checked without its library prefixes: IronPLC rejects a
    namespace-qualified type (CODESYS and TwinCAT resolve library namespaces; IronPLC has none)
    and accepts the same program without the prefix."""
    exe = ironplcc()
    decl = f"FUNCTION_BLOCK {block}\nVAR_INPUT\n  xIn : BOOL;\nEND_VAR\nEND_FUNCTION_BLOCK\n"
    use = f"PROGRAM P_Ns\nVAR\n  c : {{}}{block};\nEND_VAR\n  c(xIn := TRUE);\nEND_PROGRAM\n"
    with_ns = write(tmp_path, "ns.st", decl + use.format(ns))
    without = write(tmp_path, "plain.st", decl + use.format(""))
    assert [m for _, m in problems(exe, dialect, [with_ns])][:1] == ["error[P0002]: Syntax error"]
    assert problems(exe, dialect, [without]) == []
