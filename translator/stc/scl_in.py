"""The SCL dialect (stc --dialect=scl, or a FILE.scl): TIA Portal SCL external source text as
the generator (scl_out.py) writes it and as TIA users write it, read by the same parser and
back end as ST.

A front-end pass rewrites the text to the ST the parser reads, character for character in
place (every token keeps its line and column, so errors point into the .scl):
- `#name` (TIA's local prefix)              -> ` name`
- `"Name"` (a quoted block or type name)    -> ` Name ` (must be an identifier)
- `TYPE "X"` (a PLC data type)              -> `TYPE  X:` (ST's `X : STRUCT ...`)
- `// ...`, `{ attributes }`, `BEGIN`, `VERSION : 0.1`, `TITLE = ...`, `AUTHOR : ...`,
  `FAMILY : ...`, `NAME : ...`, `REGION ...` / `END_REGION` (balanced)  -> blanks
- TIA's IEC multi-instance types TON_TIME, TOF_TIME, TP_TIME, CTU_INT, CTD_INT, CTUD_INT
  -> the IEC names (padded)
Strings in SCL are '...' only: a "..." is always a name.
What it does not read (DATA_BLOCK, ORGANIZATION_BLOCK, global "DB".x access, Void functions,
TRY, GOTO) gets an error at its position from the pass or from the ST checker.
"""
from __future__ import annotations

import re
from .textpos import line_col

# TIA multi-instance type names of IEC timers and counters -> IEC names (see scl_out.STANDARD_FB)
_IEC_FB = {"TON_TIME": "TON", "TOF_TIME": "TOF", "TP_TIME": "TP", "CTU_INT": "CTU",
           "CTD_INT": "CTD", "CTUD_INT": "CTUD"}
_HEADER_LINE = re.compile(r"(VERSION|AUTHOR|FAMILY|NAME)\s*:[^\n;]*|TITLE\s*=[^\n]*", re.I)
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_TOKEN = re.compile(
    r"'(?:[^'$\n]|\$[^\n])*'"            # a string
    r"|\"[^\"\n]*\"?"                    # a quoted name (closing quote checked below)
    r"|\(\*.*?\*\)|\(\*"                 # a (* comment *) (left to the parser), or unclosed
    r"|/\*.*?\*/"                        # /* comment */
    r"|//[^\n]*"                         # // comment
    r"|\{[^}]*\}?"                       # { attributes }
    r"|#"
    r"|[A-Za-z_][A-Za-z0-9_]*"
    r"|[0-9][0-9A-Za-z_]*", re.S)


def _blank(s):
    return re.sub(r"[^\n]", " ", s)


def to_st(text, report):
    """The ST text of an SCL text, positions kept; report((line, col), msg) for each error.
    Returns None when an error makes the rest unreadable."""
    out = list(text)
    regions = []                 # (line, col) of the open REGIONs
    where = line_col(text)       # offset -> (line, column) in the original text

    def put(start, s):
        out[start:start + len(s)] = list(s)

    prev = None                  # the previous word token (upper-case)
    header = False               # between a block's name and its first VAR / BEGIN / STRUCT
    at_line_start = True
    pos = 0
    n = len(text)
    while pos < n:
        m = _TOKEN.search(text, pos)
        if m is None:
            break
        tok, start, end = m.group(0), m.start(), m.end()
        gap = text[pos:start]
        if "\n" in gap:
            at_line_start = True
        pos = end
        c = tok[0]
        if c == "'":
            prev = None
            at_line_start = False
            continue
        if c == '"':
            if len(tok) < 2 or not tok.endswith('"'):
                report(where(start), "P0201", "quoted name not closed on its line: missing \"")
                return None
            inner = tok[1:-1]
            if not _IDENT.fullmatch(inner):
                report(where(start), "P0202", f"quoted name \"{inner}\": stc reads only names made of "
                       "letters, digits and _ (strings in SCL are written '...')")
                prev = None
                continue
            if prev == "TYPE":       # TYPE "X"  ->  TYPE  X:   (ST's type_def wants a ':')
                put(start, " " + inner + ":")
            else:
                put(start, " " + inner + " ")
            prev = "QUOTED"
            at_line_start = False
            continue
        if tok.startswith("(*"):
            if not tok.endswith("*)") or len(tok) < 4:
                report(where(start), "P0203", "comment '(*' is not closed: missing '*)'")
                return None
            continue             # the parser blanks these itself
        if tok.startswith("/*") or tok.startswith("//") or c == "{":
            if c == "{" and not tok.endswith("}"):
                report(where(start), "P0204", "attribute '{' is not closed: missing '}'")
                return None
            put(start, _blank(tok))
            continue
        if c == "#":
            nxt = text[end:end + 1]
            if not (nxt.isalpha() or nxt == "_" or nxt == '"'):
                report(where(start), "P0205", "'#' must be followed by a local name (#name)")
            out[start] = " "
            continue
        if c.isdigit():
            # a based or typed literal (16#FF, T#5s) is one token here; skip it whole
            lit = re.compile(r"[0-9A-Za-z_]*#[+-]?[0-9A-Za-z_.]*").match(text, start)
            pos = lit.end() if lit else end
            prev = None
            at_line_start = False
            continue
        up = tok.upper()
        if text[end:end + 1] == "#":
            # a typed literal such as WORD#16#FF, T#5s, E_X#VALUE: copy it as it is
            lit = re.compile(r"#[+-]?[0-9A-Za-z_.]*(#[0-9A-Za-z_]*)?").match(text, end)
            pos = lit.end()
            prev = None
            at_line_start = False
            continue
        if up == "BEGIN":
            put(start, _blank(tok))
        elif up == "REGION" and at_line_start:
            nl = text.find("\n", start)
            nl = n if nl < 0 else nl
            regions.append(where(start))
            put(start, _blank(text[start:nl]))
            pos = nl
        elif up == "END_REGION":
            if not regions:
                report(where(start), "P0206", "END_REGION without REGION")
            else:
                regions.pop()
            put(start, _blank(tok))
            semi = re.compile(r"[ \t]*;").match(text, end)
            if semi:             # TIA writes none, but a ';' after it is harmless
                put(end, _blank(semi.group(0)))
                pos = semi.end()
        elif header and at_line_start and _HEADER_LINE.match(text, start) and \
                up in ("VERSION", "AUTHOR", "FAMILY", "NAME", "TITLE"):
            h = _HEADER_LINE.match(text, start)
            put(start, _blank(h.group(0)))
            pos = h.end()
        elif up in _IEC_FB:
            put(start, _IEC_FB[up].ljust(len(tok)))
        if up in ("FUNCTION_BLOCK", "FUNCTION", "TYPE", "ORGANIZATION_BLOCK", "DATA_BLOCK"):
            header = True
        elif up.startswith("VAR") or up in ("BEGIN", "STRUCT"):
            header = False
        prev = up
        at_line_start = False
    for r in regions:
        report(r, "P0207", "REGION not closed: missing END_REGION")
    return "".join(out)


def name_arrays(parsed):
    """TIA assigns and passes arrays of the same bounds and element type (S7-1200/1500 system
    manual, ARRAY data type: our reading); stc (like matiec) only those of one named TYPE. In a
    build with SCL sources every anonymous `Array[a..b] of T` of a declaration becomes the
    named type ARRAY_a_b_OF_T, declared once in front of the first file; so equal structure is
    one type, in the ST files of that build too. parsed: [(fname, nodes)], changed in place."""
    from . import syntax as S
    defs = {}

    def key(spec):
        if isinstance(spec, S.ArraySpec):
            if not all(isinstance(b, int) for d in spec.dims for b in d):
                return None      # a bound named by a constant: left as it is
            inner = key(spec.elem)
            if inner is None:
                return None
            dims = "_".join(f"{lo}_{hi}".replace("-", "M") for lo, hi in spec.dims)
            name = f"ARRAY_{dims}_OF_{inner}"
            if name not in defs:
                spec.elem = S.NamedType(spec.pos, inner) if isinstance(spec.elem, S.ArraySpec) else spec.elem
                defs[name] = S.TypeDef(spec.pos, name, spec, None)
            return name
        if isinstance(spec, S.NamedType):
            return spec.name
        return None

    def fix(decl):
        if isinstance(decl.type, S.ArraySpec):
            name = key(decl.type)
            if name is not None:
                decl.type = S.NamedType(decl.type.pos, name)

    for _fname, nodes in parsed:
        for n in nodes:
            blocks = list(getattr(n, "blocks", None) or [])
            if isinstance(n, S.Function) and isinstance(n.rtype, S.ArraySpec):
                name = key(n.rtype)          # an FC that returns an array
                if name is not None:
                    n.rtype = S.NamedType(n.rtype.pos, name)
            if isinstance(n, S.TypeDecl):
                for d in n.defs:
                    if isinstance(d.spec, S.StructSpec):
                        for m in d.spec.members:
                            fix(m)
            for blk in blocks:
                for d in blk.decls:
                    fix(d)
            for r in getattr(n, "resources", None) or []:
                for blk in r.blocks:
                    for d in blk.decls:
                        fix(d)
    if defs and parsed:
        first = min((d.pos for d in defs.values()), default=(1, 1))
        parsed[0][1].insert(0, S.TypeDecl(first, list(defs.values())))
