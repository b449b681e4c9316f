"""A small reader of IEC 61131-3 ST declarations, enough for the documentation tools.

It reads TYPE blocks (array, enum, struct, alias), FUNCTION_BLOCK / FUNCTION / PROGRAM with
their VAR sections and keeps each POU's body as source text, and the `(*@ ... *)` doc headers.
It does not check the code (stc and matiec do that); it only has to find the declarations.
Errors: StError with "FILE:LINE:COL: error: ..." text.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

TOKEN = re.compile(r"""
    (?P<comment>\(\*.*?\*\))
  | (?P<opencomment>\(\*)
  | (?P<ws>\s+)
  | (?P<string>'(?:[^'$]|\$.)*'|"(?:[^"$]|\$.)*")
  | (?P<located>%[IQM][XBWDL]?[0-9]+(?:\.[0-9]+)*|%[IQM]\*)
  | (?P<typed>[A-Za-z_][A-Za-z0-9_]*\#[-+]?[0-9A-Za-z_.#:]+)
  | (?P<number>[0-9][0-9_]*(?:\#[0-9A-Fa-f_]+)?(?:\.[0-9][0-9_]*)?(?:[eE][-+]?[0-9]+)?)
  | (?P<ident>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<sym>:=|=>|\.\.|<=|>=|<>|\*\*|[-+*/&=<>()\[\],;:.^#])
""", re.S | re.X)

ELEMENTARY = {"BOOL", "BYTE", "WORD", "DWORD", "LWORD", "SINT", "INT", "DINT", "LINT", "USINT",
              "UINT", "UDINT", "ULINT", "REAL", "LREAL", "TIME", "DATE", "DT", "TOD", "STRING",
              "WSTRING", "DATE_AND_TIME", "TIME_OF_DAY"}
VAR_KINDS = ("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR_TEMP", "VAR_EXTERNAL", "VAR_GLOBAL",
             "VAR")
POU_KINDS = {"FUNCTION_BLOCK": "END_FUNCTION_BLOCK", "FUNCTION": "END_FUNCTION",
             "PROGRAM": "END_PROGRAM"}


class StError(Exception):
    pass


@dataclass
class Tok:
    kind: str
    text: str
    pos: int
    line: int
    col: int

    @property
    def up(self):
        return self.text.upper()


@dataclass
class TypeSpec:
    """kind: 'elementary', 'derived', 'array' (dims, base), 'string' (length)."""
    kind: str
    name: str = ""
    dims: list = field(default_factory=list)     # [(lower, upper)] as source text
    base: "TypeSpec | None" = None

    def text(self):
        if self.kind == "array":
            dims = ", ".join(f"{lo}..{hi}" for lo, hi in self.dims)
            return f"ARRAY[{dims}] OF {self.base.text()}"
        return self.name


@dataclass
class Var:
    name: str
    type: TypeSpec
    init: str | None = None
    address: str | None = None
    comment: str | None = None
    line: int = 0


@dataclass
class VarSection:
    kind: str                   # VAR_INPUT ...
    constant: bool = False
    retain: bool = False
    vars: list = field(default_factory=list)
    # stand-alone comments inside the block (not a declaration's trailing comment):
    # [(index of the variable they stand before (len(vars): before END_VAR), text)]
    groups: list = field(default_factory=list)
    # indexes of the variables a blank line stands before (where a group ends)
    breaks: list = field(default_factory=list)


@dataclass
class DataType:
    name: str
    kind: str                   # array | enum | struct | alias
    spec: TypeSpec | None = None
    values: list = field(default_factory=list)       # enum: [(name, comment)]
    members: list = field(default_factory=list)      # struct: [Var]
    init: str | None = None
    comment: str | None = None
    file: str = ""
    line: int = 0


@dataclass
class Pou:
    name: str
    kind: str                   # FUNCTION_BLOCK | FUNCTION | PROGRAM
    sections: list
    body: str
    return_type: TypeSpec | None = None
    doc: str | None = None      # the (*@ ... *) header before it, without the delimiters
    file: str = ""
    line: int = 0


@dataclass
class Unit:
    file: str
    types: list
    pous: list
    file_doc: str | None = None


def tokenize(text, path):
    toks, pos, line, line_start = [], 0, 1, 0
    n = len(text)
    while pos < n:
        m = TOKEN.match(text, pos)
        if not m:
            raise StError(f"{path}:{line}:{pos - line_start + 1}: error: unexpected character "
                          f"{text[pos]!r}")
        kind = m.lastgroup
        s = m.group()
        if kind == "opencomment":
            raise StError(f"{path}:{line}:{pos - line_start + 1}: error: comment '(*' is not "
                          f"closed")
        if kind == "comment" or kind == "ws" or kind == "string":
            pass
        if kind != "ws":
            toks.append(Tok(kind, s, pos, line, pos - line_start + 1))
        nl = s.count("\n")
        if nl:
            line += nl
            line_start = pos + s.rindex("\n") + 1
        pos = m.end()
    return toks


def comment_text(tok):
    return tok.text[2:-2].strip()


class Parser:
    def __init__(self, text, path):
        self.text, self.path = text, path
        self.all = tokenize(text, path)
        self.toks = [t for t in self.all if t.kind != "comment"]
        self.i = 0

    # -- helpers
    def err(self, tok, msg):
        if tok is None:
            return StError(f"{self.path}: error: {msg} (end of file)")
        return StError(f"{self.path}:{tok.line}:{tok.col}: error: {msg}")

    def peek(self, k=0):
        j = self.i + k
        return self.toks[j] if j < len(self.toks) else None

    def next(self):
        t = self.peek()
        if t is None:
            raise self.err(None, "unexpected end of file")
        self.i += 1
        return t

    def expect(self, text):
        t = self.next()
        if t.up != text:
            raise self.err(t, f"expected {text}, found {t.text!r}")
        return t

    def accept(self, text):
        t = self.peek()
        if t is not None and t.up == text:
            self.i += 1
            return t
        return None

    def ident(self, what):
        t = self.next()
        if t.kind != "ident":
            raise self.err(t, f"expected {what}, found {t.text!r}")
        return t

    def comments_between(self, a, b):
        return [comment_text(t) for t in self.all if t.kind == "comment" and a <= t.pos < b]

    def trailing_comment(self, tok):
        """A comment starting on the same line right after tok (the ';' of a declaration)."""
        t = self.trailing_token(tok)
        return comment_text(t) if t is not None else None

    def trailing_token(self, tok):
        for t in self.all:
            if t.kind == "comment" and t.pos > tok.pos:
                between = self.text[tok.pos + len(tok.text):t.pos]
                if "\n" not in between and not between.strip():
                    return t
                return None
        return None

    def group_comments(self, after, before):
        """Stand-alone comments between the token `after` (VAR keyword, qualifier or the ';' of
        a declaration) and the position `before`, without after's trailing comment."""
        trail = self.trailing_token(after) if after.text == ";" else None
        return [comment_text(t) for t in self.all
                if t.kind == "comment" and after.pos < t.pos < before and t is not trail]

    def doc_before(self, tok, since):
        """The last (*@ ... *) comment between `since` and tok."""
        docs = [t for t in self.all if t.kind == "comment" and since <= t.pos < tok.pos
                and t.text.startswith("(*@")]
        return docs[-1].text[3:-2] if docs else None

    # -- grammar
    def parse(self):
        types, pous, file_doc = [], [], None
        for t in self.all:
            if t.kind == "comment" and t.text.startswith("(*@") and \
                    t.text[3:].lstrip().lower().startswith("file"):
                file_doc = t.text[3:-2]
                break
        last_end = 0
        while self.peek() is not None:
            t = self.next()
            if t.up == "TYPE":
                types += self.type_block()
            elif t.up in POU_KINDS:
                pou = self.pou(t)
                pou.doc = self.doc_before(t, last_end)
                pous.append(pou)
            elif t.up == "CONFIGURATION":
                self.skip_to("END_CONFIGURATION")
            else:
                raise self.err(t, f"expected TYPE, FUNCTION_BLOCK, FUNCTION, PROGRAM or "
                                  f"CONFIGURATION, found {t.text!r}")
            last_end = self.toks[self.i - 1].pos
        return Unit(self.path, types, pous, file_doc)

    def skip_to(self, end):
        while self.next().up != end:
            pass

    def type_block(self):
        out = []
        while not self.accept("END_TYPE"):
            name = self.ident("a type name")
            self.expect(":")
            dt = DataType(name.text, "alias", file=self.path, line=name.line)
            t = self.peek()
            if t is not None and t.text == "(":
                self.next()
                dt.kind = "enum"
                while True:
                    v = self.ident("an enum value")
                    nxt = self.peek()
                    if nxt is not None and nxt.text == ":=":
                        raise self.err(nxt, "enum values with explicit numbers are not supported")
                    sep = self.next()
                    comments = self.comments_between(v.pos, self.peek().pos if self.peek()
                                                     else len(self.text))
                    dt.values.append((v.text, comments[0] if comments else None))
                    if sep.text == ")":
                        break
                    if sep.text != ",":
                        raise self.err(sep, f"expected ',' or ')', found {sep.text!r}")
            elif t is not None and t.up == "STRUCT":
                self.next()
                dt.kind = "struct"
                while not self.accept("END_STRUCT"):
                    dt.members += self.var_decl()
            else:
                dt.spec = self.type_spec()
                dt.kind = "array" if dt.spec.kind == "array" else "alias"
            if self.accept(":="):
                dt.init = self.init_text()
            semi = self.expect(";")
            comments = self.comments_between(self.last_end_before(name), name.pos)
            dt.comment = comments[-1] if comments and not comments[-1].startswith("@") else None
            del semi
            out.append(dt)
        return out

    def last_end_before(self, tok):
        j = self.toks.index(tok)
        prev = self.toks[j - 1] if j > 0 else None
        return prev.pos + len(prev.text) if prev else 0

    def type_spec(self):
        t = self.next()
        if t.up == "ARRAY":
            self.expect("[")
            dims = []
            while True:
                lo = self.bound()
                self.expect("..")
                hi = self.bound()
                dims.append((lo, hi))
                sep = self.next()
                if sep.text == "]":
                    break
                if sep.text != ",":
                    raise self.err(sep, f"expected ',' or ']', found {sep.text!r}")
            self.expect("OF")
            return TypeSpec("array", dims=dims, base=self.type_spec())
        if t.kind != "ident":
            raise self.err(t, f"expected a type, found {t.text!r}")
        if t.up in ("STRING", "WSTRING") and self.peek() is not None and self.peek().text in "[(":
            close = "]" if self.next().text == "[" else ")"     # STRING[n], or STRING(n) (vendor ST)
            n = self.next()
            self.expect(close)
            return TypeSpec("string", name=f"{t.up}[{n.text}]")
        if t.up == "POINTER" and self.peek() is not None and self.peek().up == "TO":
            self.next()                                           # POINTER TO T (vendor ST)
            return TypeSpec("pointer", base=self.type_spec())
        if t.up in ELEMENTARY:
            return TypeSpec("elementary", name=t.up)
        name = t.text
        while self.peek() is not None and self.peek().text == "." and self.peek(1) is not None \
                and self.peek(1).kind == "ident":
            self.next()                                           # Library.Type (a namespace)
            name += "." + self.next().text
        return TypeSpec("derived", name=name)

    def bound(self):
        sign = ""
        if self.peek() is not None and self.peek().text in "+-":
            sign = self.next().text
        t = self.next()
        if t.kind not in ("number", "ident"):
            raise self.err(t, f"expected an array bound, found {t.text!r}")
        return sign + t.text

    def init_text(self):
        """Source text of an initial value, up to the ';' at bracket depth 0."""
        start = self.peek()
        depth, end = 0, start
        while True:
            t = self.peek()
            if t is None:
                raise self.err(start, "initial value without ';'")
            if t.text in "([":
                depth += 1
            elif t.text in ")]":
                depth -= 1
            elif t.text == ";" and depth == 0:
                break
            end = self.next()
        return self.text[start.pos:end.pos + len(end.text)]

    def var_decl(self):
        names = [self.ident("a variable name")]
        while self.accept(","):
            names.append(self.ident("a variable name"))
        address = None
        if self.accept("AT"):
            a = self.next()
            if a.kind != "located":
                raise self.err(a, f"expected a located address, found {a.text!r}")
            address = a.text
        self.expect(":")
        spec = self.type_spec()
        init = self.init_text() if self.accept(":=") else None
        semi = self.expect(";")
        comment = self.trailing_comment(semi)
        return [Var(n.text, spec, init, address, comment, n.line) for n in names]

    def pou(self, kw):
        name = self.ident("a POU name")
        ret = None
        if kw.up == "FUNCTION":
            self.expect(":")
            ret = self.type_spec()
        sections = []
        while self.peek() is not None and self.peek().up in VAR_KINDS:
            k = self.next().up
            sec = VarSection(k)
            while self.peek() is not None and self.peek().up in ("CONSTANT", "RETAIN",
                                                                 "NON_RETAIN"):
                q = self.next().up
                sec.constant |= q == "CONSTANT"
                sec.retain |= q == "RETAIN"
            while True:
                prev, nxt = self.toks[self.i - 1], self.peek()
                if nxt is None:
                    raise self.err(kw, f"{k} without END_VAR")
                for c in self.group_comments(prev, nxt.pos):
                    sec.groups.append((len(sec.vars), c))
                if sec.vars and re.search(r"\n[ \t]*\n", self.text[prev.pos:nxt.pos]):
                    sec.breaks.append(len(sec.vars))
                if self.accept("END_VAR"):
                    break
                sec.vars += self.var_decl()
            sections.append(sec)
        end_kw = POU_KINDS[kw.up]
        body_start = self.toks[self.i - 1].pos + len(self.toks[self.i - 1].text)
        while True:
            t = self.peek()
            if t is None:
                raise self.err(kw, f"{kw.up} {name.text} without {end_kw}")
            if t.up == end_kw:
                break
            self.next()
        body = self.text[body_start:t.pos]
        self.next()
        return Pou(name.text, kw.up, sections, dedent_body(body), ret, None, self.path, kw.line)


def dedent_body(body):
    lines = body.strip("\n").split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    while lines and not lines[0].strip():
        lines.pop(0)
    indents = [len(x) - len(x.lstrip()) for x in lines if x.strip()]
    cut = min(indents) if indents else 0
    return "\n".join(x[cut:].rstrip() for x in lines) + "\n"


def parse_file(path):
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise StError(f"{path}: error: {e.strerror}")
    except UnicodeDecodeError:
        raise StError(f"{path}: error: not UTF-8 text")
    return Parser(text, path).parse()


# -- doc headers --------------------------------------------------------------------------

SECTION = re.compile(r"^@(\w+)\s*(.*)$")


def parse_doc(doc):
    """A `(*@ block NAME ... *)` header: {'kind', 'name', 'purpose', 'interface': rows,
    'behaviour', 'example'} (texts with the common indentation removed)."""
    lines = doc.split("\n")
    head = lines[0].strip().split()
    out = {"kind": head[0] if head else "", "name": head[1] if len(head) > 1 else "",
           "sections": {}}
    cur = None
    for line in lines[1:]:
        m = SECTION.match(line.strip())
        if m and not line.startswith("  "):
            cur = m.group(1)
            out["sections"][cur] = [m.group(2)] if m.group(2) else []
        elif cur is not None:
            out["sections"][cur].append(line)
    for k, v in list(out["sections"].items()):
        while v and not v[-1].strip():
            v.pop()
        indents = [len(x) - len(x.lstrip()) for x in v if x.strip()]
        cut = min(indents) if indents else 0
        out["sections"][k] = [x[cut:].rstrip() for x in v]
    rows = []
    for line in out["sections"].get("interface", []):
        if line.strip().startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            rows.append(cells)
    out["interface"] = rows
    return out
