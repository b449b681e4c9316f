"""The TwinCAT 3 and CODESYS V3 dialects (stc --dialect=twincat|codesys, or a FILE.twincat.st /
FILE.codesys.st): the ST an integrator writes in those IDEs around the portable blocks (the
vendor glue of dist/glue/), read by the same parser and back end as ST.

A front-end pass rewrites the text to the ST the parser reads, in place (every token keeps its
line and column, so errors point into the file):
- `{ attribute ... }` / `{ pragmas }`, `// ...`     -> blanks
- a library namespace before a name: `Tc2_ModbusSrv.FB_MBReadRegs`, `ModbusFB.ClientTCP`,
  `Tc2_System.MEMCPY` (the names in NAMESPACES)      -> blanks before the name
- `STRING(15)` (TwinCAT / CODESYS length syntax)     -> `STRING[15]`
- `END_IF` (and END_CASE, END_FOR, END_WHILE, END_REPEAT) without its `;`, as the IDEs write
  them -> the `;` is added in place of the next blank (or right after the keyword).
- a CASE label `Enum.Value:` (first on its line or after `;`) -> `Enum#Value:`
The checker then allows, in these files only (types.PointerT): `POINTER TO T`, `PVOID`, `ADR(x)`,
`SIZEOF(x)` (UDINT), `p^`, `MEMCPY(destAddr, srcAddr, n)` (Tc2_System; CODESYS: SysMemCpy of
SysMem), a `STRING(n)` up to STRING's length, and `Enum.Value` for an enumeration value.
"""
from __future__ import annotations

import re
from .textpos import line_col

DIALECTS = ("twincat", "codesys")
# the library namespaces the glue and the stand-ins qualify names with (upper case)
NAMESPACES = {"TC2_MODBUSSRV", "TC2_SYSTEM", "TC2_STANDARD", "MODBUSFB", "STANDARD", "SYSMEM"}
_END_STMT = {"END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT"}
_TOKEN = re.compile(
    r"'(?:[^'$\n]|\$[^\n])*'"            # a string
    r"|\(\*.*?\*\)|\(\*"                 # a (* comment *) (left to the parser), or unclosed
    r"|//[^\n]*"                         # // comment
    r"|\{[^}]*\}?"                       # { pragma }
    r"|[A-Za-z_][A-Za-z0-9_]*"
    r"|[0-9][0-9A-Za-z_#.]*"
    r"|\S", re.S)


def _case_label_start(toks, i):
    """Token i starts a line's first element (a CASE label is the first thing on its line
    or follows ';')."""
    if i == 0:
        return True
    prev = toks[i - 1]
    return prev[0] == ";" or prev[0].upper() in ("OF", "THEN", "ELSE", "DO")


def dialect_of_name(fname):
    """'twincat' / 'codesys' for FILE.twincat.st / FILE.codesys.st, else None."""
    low = fname.lower()
    for d in DIALECTS:
        if low.endswith(f".{d}.st"):
            return d
    return None


def to_st(text, report):
    """The ST text of a TwinCAT / CODESYS text, positions kept; report((line, col), msg) for
    each error. Returns None when an error makes the rest unreadable."""
    out = list(text)
    where = line_col(text)       # offset -> (line, column) in the original text

    def blank(start, end):
        for k in range(start, end):
            if out[k] != "\n":
                out[k] = " "

    inserts = []                 # offsets after which a ';' goes (no blank to put it in)
    toks = [(m.group(0), m.start(), m.end()) for m in _TOKEN.finditer(text)]
    ok = True
    for i, (tok, start, end) in enumerate(toks):
        nxt = toks[i + 1] if i + 1 < len(toks) else None
        c = tok[0]
        if c == "{":
            if not tok.endswith("}"):
                report(where(start), "P0301", "unclosed pragma '{': missing '}'")
                ok = False
                break
            blank(start, end)
        elif tok.startswith("//"):
            blank(start, end)
        elif tok.startswith("(*") and not tok.endswith("*)"):
            report(where(start), "P0302", "unclosed comment '(*'")
            ok = False
            break
        elif c.isalpha() or c == "_":
            up = tok.upper()
            after2 = toks[i + 2] if i + 2 < len(toks) else None
            after3 = toks[i + 3] if i + 3 < len(toks) else None
            if up not in NAMESPACES and nxt is not None and nxt[0] == "." and nxt[1] == end \
                    and after2 is not None and after2[1] == end + 1 \
                    and (after2[0][0].isalpha() or after2[0][0] == "_") \
                    and after3 is not None and after3[0] == ":" \
                    and not text.startswith(":=", after3[1]) and _case_label_start(toks, i):
                out[end] = "#"     # a CASE label Enum.Value: -> Enum#Value
            elif up in NAMESPACES and nxt is not None and nxt[0] == "." and nxt[1] == end:
                after = toks[i + 2] if i + 2 < len(toks) else None
                if after is not None and (after[0][0].isalpha() or after[0][0] == "_") \
                        and after[1] == end + 1:
                    blank(start, end + 1)
            elif up == "STRING" and nxt is not None and nxt[0] == "(" and i + 3 < len(toks) \
                    and toks[i + 2][0].isdigit() and toks[i + 3][0] == ")":
                out[nxt[1]] = "["
                out[toks[i + 3][1]] = "]"
            elif up in _END_STMT and (nxt is None or nxt[0] != ";"):
                if end < len(text) and text[end] in " \t":
                    out[end] = ";"
                else:
                    inserts.append(end)
    if not ok:
        return None
    for off in reversed(inserts):
        out.insert(off, ";")
    return "".join(out)
