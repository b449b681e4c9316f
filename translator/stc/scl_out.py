"""ST (matiec dialect) -> TIA Portal SCL external source files, generated from stc's own syntax
tree (one source of truth: st_lib/*/*.st; the .scl is never edited by hand).

    python -m stc.scl_out -o OUTDIR FILE.st...      # FILE.st in import order

What changes (docs/wiring-s7.md, "What the generator writes"):
- TIA has no enumerations (our reading of the S7-1200/1500 system manual, data types: none is
  listed): every enumerated type becomes Int, and each block that uses one declares all of its
  values as local constants (`VAR CONSTANT MIP_ERR_NONE : Int := 0; ... END_VAR`) with the
  numbers stc and matiec give them (0, 1, ... in declaration order). Our choice: local, not a
  global constant table, so each block imports alone from its external source.
- TIA has no array type names: `MIP_T_Block` becomes `Array[0..122] of Word` everywhere.
- `#` in front of every local, block names quoted ("MIP_Sender"), `BEGIN` before the body,
  `{ S7_Optimized_Access := 'TRUE' }` and `VERSION : MAJOR.MINOR` (from MIP_Version.st) on
  every block; IEC timers as TIA names its multi-instances (TON -> TON_TIME ...).
- CASE labels of an enumeration become the number with the name in a comment (our choice: the
  constant name as a label is not something we could confirm TIA accepts).
- A FUNCTION's VAR becomes VAR_TEMP (TIA FCs have no static data) and is set to its initial
  value at the start of the body, as IEC initialises a function's locals on every call.
- An FB with the PLCopen outputs xBusy, xError and eErrorId gets an LGF-style `status : Word`
  output, derived from them at the end of its body (REGION "LGF status"); a combined block
  (MIP_Link: xSendBusy, xSendError, eSendErrorId and xRecvBusy, ...) gets one per side,
  `sendStatus` and `recvStatus` (st_lib/CONVENTIONS.md, "status-word").
- Comments are kept where they were (between the statements and declarations they followed).
"""
from __future__ import annotations

import argparse
import os
import re
import sys

from . import oneline, parser, scl_status
from . import syntax as S
from .diag import Diagnostics

# IEC elementary type -> how TIA's editor spells it (the language is case-insensitive)
ELEMENTARY = {n.upper(): n for n in (
    "Bool Byte Word DWord LWord SInt Int DInt LInt USInt UInt UDInt ULInt Real LReal Time "
    "LTime Date Time_Of_Day Date_And_Time String WString Char WChar").split()}
ELEMENTARY["TOD"] = "Time_Of_Day"
ELEMENTARY["DT"] = "Date_And_Time"
# IEC standard FBs -> TIA's multi-instance type (S7-1200/1500 system manual, "Basic
# instructions": timer operations TON/TOF/TP as IEC_TIMER instances TON_TIME ...; counters
# CTU_INT ...). R_TRIG / F_TRIG keep their names.
STANDARD_FB = {"TON": "TON_TIME", "TOF": "TOF_TIME", "TP": "TP_TIME",
               "CTU": "CTU_INT", "CTD": "CTD_INT", "CTUD": "CTUD_INT",
               "R_TRIG": "R_TRIG", "F_TRIG": "F_TRIG"}



class SclError(Exception):
    """FILE:LINE:COL: error: MESSAGE [CODE] (one line for the user)."""


def _error(where, code, msg):
    """The SclError of the generator's problem code (a G row of stc/problems.csv) at where
    (FILE:LINE:COL, FILE or the generator's name)."""
    return SclError(f"{where}: error: {msg} [{code}]")


_SECTION = re.compile(r"\(\* ----+ ([^\n]*?)(?: ----+)? ?(?:\*\))?$", re.M)
_COMMENT = re.compile(r"\(\*.*?\*\)|'(?:[^'$\n]|\$[^\n])*'|\"(?:[^\"$\n]|\$[^\n])*\"", re.S)


def _comments(text):
    """[(line, col, end_line, text)] of the (* *) comments of an ST text."""
    out = []
    for m in _COMMENT.finditer(text):
        t = m.group(0)
        if not t.startswith("(*"):
            continue
        line = text.count("\n", 0, m.start()) + 1
        col = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
        out.append((line, col, line + t.count("\n"), t))
    return out


class _Lib:
    """What the generator knows of the whole library: types, blocks, functions."""

    def __init__(self):
        self.enums = {}        # type name -> [(item, value)]
        self.enum_of = {}      # item name -> type name
        self.arrays = {}       # alias name -> ArraySpec
        self.structs = {}      # struct type name -> TypeDef
        self.fbs = set()
        self.functions = set()
        self.names = {}        # upper-case name -> name as written (for output spelling)

    def add(self, nodes, text):
        for n in nodes:
            if isinstance(n, S.TypeDecl):
                for d in n.defs:
                    self.names[d.name] = _spelled(text, d.pos, d.name)
                    if isinstance(d.spec, S.EnumSpec):
                        vals, nxt = [], 0
                        for item, value, ipos in d.spec.items:
                            nxt = value if value is not None else nxt
                            vals.append((_spelled(text, ipos, item), nxt))
                            self.enum_of[item] = d.name
                            nxt += 1
                        self.enums[d.name] = vals
                    elif isinstance(d.spec, S.ArraySpec):
                        self.arrays[d.name] = d.spec
                    elif isinstance(d.spec, S.StructSpec):
                        self.structs[d.name] = d
            elif isinstance(n, S.FunctionBlock):
                self.fbs.add(n.name)
                self.names[n.name] = _spelled(text, n.pos, n.name)
            elif isinstance(n, S.Function):
                self.functions.add(n.name)
                self.names[n.name] = _spelled(text, n.pos, n.name)


def _spelled(text, pos, upper):
    """The name as the source writes it at pos (the syntax tree keeps it upper-case)."""
    lines = text.split("\n") if isinstance(text, str) else text
    try:
        line = lines[pos[0] - 1]
    except IndexError:
        return upper
    seg = line[pos[1] - 1:pos[1] - 1 + len(upper)]
    return seg if seg.upper() == upper else upper


def _walk(x):
    """Every syntax node below x (lists, tuples and nodes)."""
    if isinstance(x, (list, tuple)):
        for y in x:
            yield from _walk(y)
    elif isinstance(x, S.Node):
        yield x
        for k in x.__slots__:
            if k != "pos":
                yield from _walk(getattr(x, k, None))


class _Pou:
    """Writes one FUNCTION or FUNCTION_BLOCK."""

    def __init__(self, gen, node, text, comments):
        self.g, self.lib, self.n = gen, gen.lib, node
        self.lines = text.split("\n")
        self.comments = comments      # shared list of pending comments of the file
        self.locals = {}              # upper -> spelling
        for blk in node.blocks:
            for d in blk.decls:
                for name, pos in d.names:
                    self.locals[name] = _spelled(self.lines, pos, name)
        self.is_fn = isinstance(node, S.Function)
        if self.is_fn:
            self.locals[node.name] = self.lib.names.get(node.name, node.name)
        self.out = []

    # ---- comments
    def flush_comments(self, before_line, indent, same_line=None, slash=False):
        """Write the pending comments that start before before_line (own lines); a comment on
        same_line goes to the end of the last written line instead (slash: as a // comment,
        which TIA takes as a declaration's comment)."""
        while self.comments and self.comments[0][0] < before_line:
            line, _col, _end, t = self.comments.pop(0)
            if same_line is not None and line == same_line and self.out and "\n" not in t:
                self.out[-1] += "  " + ("// " + t[2:-2].strip() if slash else t)
            else:
                # continuation lines as they were: their indentation is the comment's layout
                self.out.extend(x.rstrip() if i else indent + x
                                for i, x in enumerate(t.split("\n")))

    # ---- types
    def type_ref(self, t):
        if isinstance(t, S.NamedType):
            n = t.name
            if n in ELEMENTARY:
                return ELEMENTARY[n]
            if n in self.lib.enums:
                return "Int"
            if n in self.lib.arrays:
                return self.type_ref(self.lib.arrays[n])
            if n in STANDARD_FB:
                return STANDARD_FB[n]
            if n in self.lib.fbs or n in self.lib.structs:
                return f'"{self.lib.names.get(n, n)}"'
            return n
        if isinstance(t, S.ArraySpec):
            dims = ", ".join(f"{self.bound(lo)}..{self.bound(hi)}" for lo, hi in t.dims)
            return f"Array[{dims}] of {self.type_ref(t.elem)}"
        if isinstance(t, S.StringRef):
            return f"{ELEMENTARY.get(t.base, t.base)}[{t.size}]"
        raise _error(f"{self.g.fname}:{t.pos[0]}:{t.pos[1]}", "G0101", "this type has no SCL "
                     f"form in the generator ({type(t).__name__})")

    def bound(self, b):
        if isinstance(b, S.ConstBound):
            return "#" + self.locals.get(b.name, b.name) if b.name in self.locals else b.name
        return str(b)

    def enum_type(self, t):
        """The enumerated type name of a declared type, or None."""
        return t.name if isinstance(t, S.NamedType) and t.name in self.lib.enums else None

    # ---- expressions
    def expr(self, e):
        if isinstance(e, (S.IntLit, S.RealLit, S.TimeLit, S.StringLit)):
            return e.text           # as written
        if isinstance(e, S.BoolLit):
            return "TRUE" if e.value else "FALSE"
        if isinstance(e, S.TypedLit):
            if e.kind == "ident" and e.type_name in self.lib.enums:
                return self.enum_ref(e.value)
            return e.text
        if isinstance(e, S.Name):
            return self.name(e.name)
        if isinstance(e, S.Field):
            return f"{self.expr(e.base)}.{self.member(e)}"
        if isinstance(e, S.Index):
            return f"{self.expr(e.base)}[{', '.join(self.expr(i) for i in e.indexes)}]"
        if isinstance(e, S.Call):
            return f"{self.callee(e.name)}({self.args(e.args)})"
        if isinstance(e, S.BinOp):
            op = {"AND": "AND", "OR": "OR", "XOR": "XOR", "MOD": "MOD"}.get(e.op, e.op)
            return f"{self.expr(e.left)} {op} {self.expr(e.right)}"
        if isinstance(e, S.UnOp):
            return f"NOT {self.expr(e.operand)}" if e.op == "NOT" else f"{e.op}{self.expr(e.operand)}"
        if isinstance(e, S.Paren):
            return f"({self.expr(e.inner)})"
        raise _error(f"{self.g.fname}:{e.pos[0]}:{e.pos[1]}", "G0102", f"{type(e).__name__} has "
                     "no SCL form in the generator")

    def member(self, e):
        return _spelled(self.lines, e.pos, e.name)

    def name(self, n):
        if n in self.locals:
            return "#" + self.locals[n]
        if n in self.lib.enum_of:
            return self.enum_ref(n)
        return self.lib.names.get(n, n)

    def enum_ref(self, item):
        self.used_enums.add(self.lib.enum_of[item])
        return "#" + self.enum_spell(item)

    def enum_spell(self, item):
        for n, _v in self.lib.enums[self.lib.enum_of[item]]:
            if n.upper() == item:
                return n
        return item

    def enum_value(self, item):
        for n, v in self.lib.enums[self.lib.enum_of[item]]:
            if n.upper() == item:
                return v
        return None

    def callee(self, name):
        if name in self.lib.functions or name in self.lib.fbs:
            return f'"{self.lib.names.get(name, name)}"'
        return name

    def args(self, args):
        out = []
        for a in args:
            if isinstance(a, S.ArgPos):
                out.append(self.expr(a.value))
            elif isinstance(a, S.ArgIn):
                out.append(f"{self.arg_name(a)} := {self.expr(a.value)}")
            else:
                out.append(f"{'NOT ' if a.negate else ''}{self.arg_name(a)} => {self.expr(a.target)}")
        return ", ".join(out)

    def arg_name(self, a):
        return _spelled(self.lines, a.pos, a.name)

    def init(self, v, enum_t):
        """An initial value: an enumeration's value as its number (name in a comment)."""
        if isinstance(v, (S.Name, S.TypedLit)) and enum_t is not None:
            item = v.name if isinstance(v, S.Name) else v.value
            if item in self.lib.enum_of:
                self.used_enums.add(self.lib.enum_of[item])
                return f"{self.enum_value(item)} (* {self.enum_spell(item)} *)"
        if isinstance(v, S.StructInit):
            return "(" + ", ".join(f"{_spelled(self.lines, pos, name)} := {self.init(val, None)}"
                                   for name, val, pos in v.items) + ")"
        if isinstance(v, S.ArrayInit):
            items = []
            for count, val in v.items:
                sv = self.init(val, None) if val is not None else ""
                items.append(f"{count}({sv})" if count is not None else sv)
            return "[" + ", ".join(items) + "]"
        return self.expr(v)

    # ---- statements
    def stmts(self, body, ind, top=False):
        for s in body:
            if top:
                self.regions(s.pos[0], ind)
            self.flush_comments(s.pos[0], ind)
            self.stmt(s, ind)

    def orelse(self, body, ind):
        """An IF's or a CASE's ELSE at ind and its statements one level in, when it has one."""
        if body is not None:
            self.out.append(f"{ind}ELSE")
            self.stmts(body, ind + "    ")

    def regions(self, before_line, ind):
        """A section comment `(* ---- name ---- *)` between the body's top-level statements
        starts a REGION named so (TIA folds it), up to the next one or the end of the body."""
        while self.comments and self.comments[0][0] < before_line:
            line, _c, end, t = self.comments[0]
            m = _SECTION.match(t)
            if not m:
                self.flush_comments(line + 1, ind)
                continue
            self.comments.pop(0)
            self.close_region(ind)
            name = m.group(1).strip().rstrip("-").strip()
            self.out.append(f"{ind}REGION {name}")
            self.open_region = True
            if end != line:          # the rest of a longer section comment stays a comment
                self.out.extend(x.rstrip() if i else ind + x for i, x in enumerate(t.split("\n")))

    def close_region(self, ind):
        if getattr(self, "open_region", False):
            self.out.append(f"{ind}END_REGION")
            self.open_region = False

    def trail(self, line):
        """A comment that followed on the source line `line` goes to the end of the last line."""
        self.flush_comments(line + 1, "", same_line=line)

    def stmt(self, s, ind):
        o = self.out
        if isinstance(s, S.Assign):
            o.append(f"{ind}{self.expr(s.target)} := {self.expr(s.value)};")
            self.trail(s.pos[0])
        elif isinstance(s, S.CallStmt):
            name = self.name(s.name) if s.name in self.locals else self.callee(s.name)
            o.append(f"{ind}{name}({self.args(s.args)});")
            self.trail(s.pos[0])
        elif isinstance(s, S.If):
            for i, (cond, body) in enumerate(s.branches):
                o.append(f"{ind}{'IF' if i == 0 else 'ELSIF'} {self.expr(cond)} THEN")
                self.trail(cond.pos[0])
                self.stmts(body, ind + "    ")
            self.orelse(s.orelse, ind)
            o.append(f"{ind}END_IF;")
        elif isinstance(s, S.Case):
            o.append(f"{ind}CASE {self.expr(s.selector)} OF")
            for item in s.items:
                if isinstance(item, S.CaseLabels):
                    self.flush_comments(item.pos[0], ind + "    ")
                    o.append(f"{ind}    {', '.join(self.label(lo, hi) for lo, hi in item.labels)}:")
                else:
                    self.flush_comments(item.pos[0], ind + "        ")
                    self.stmt(item, ind + "        ")
            self.orelse(s.orelse, ind + "    ")
            o.append(f"{ind}END_CASE;")
        elif isinstance(s, S.For):
            by = f" BY {self.expr(s.step)}" if s.step is not None else ""
            o.append(f"{ind}FOR {self.expr(s.var)} := {self.expr(s.start)} TO {self.expr(s.end)}{by} DO")
            self.stmts(s.body, ind + "    ")
            o.append(f"{ind}END_FOR;")
        elif isinstance(s, S.While):
            o.append(f"{ind}WHILE {self.expr(s.cond)} DO")
            self.stmts(s.body, ind + "    ")
            o.append(f"{ind}END_WHILE;")
        elif isinstance(s, S.Repeat):
            o.append(f"{ind}REPEAT")
            self.stmts(s.body, ind + "    ")
            o.append(f"{ind}UNTIL {self.expr(s.cond)}")
            o.append(f"{ind}END_REPEAT;")
        elif isinstance(s, S.Exit):
            o.append(f"{ind}EXIT;")
        elif isinstance(s, S.Continue):
            o.append(f"{ind}CONTINUE;")
        elif isinstance(s, S.Return):
            o.append(f"{ind}RETURN;")
        elif isinstance(s, S.Empty):
            o.append(f"{ind};")
        else:
            raise _error(f"{self.g.fname}:{s.pos[0]}:{s.pos[1]}", "G0103", f"{type(s).__name__} "
                         "has no SCL form in the generator")

    def label(self, lo, hi):
        def one(v):
            if isinstance(v, int):
                return str(v)
            item = v.name if isinstance(v, S.Name) else getattr(v, "value", None)
            if isinstance(item, str) and item in self.lib.enum_of:
                self.used_enums.add(self.lib.enum_of[item])
                return f"{self.enum_value(item)} (* {self.enum_spell(item)} *)"
            return self.expr(v)
        return one(lo) if hi is None else f"{one(lo)}..{one(hi)}"

    # ---- the block
    def lgf_status(self):
        """The LGF-style status outputs this FB gets (stc.scl_status.sides)."""
        if self.is_fn or any(isinstance(x, S.Return) for x in _walk(self.n.body)):
            return []   # a function, or a RETURN that would skip the update
        return scl_status.sides(self.n.blocks, self.locals)

    def write(self, version):
        n = self.n
        self.used_enums = set()
        lgf = self.lgf_status()
        # in source order, so that each comment lands where it was
        before = self.out = []
        self.flush_comments(n.pos[0], "")
        name = self.lib.names.get(n.name, n.name)
        head = []
        if self.is_fn:
            head.append(f'FUNCTION "{name}" : {self.type_ref(n.rtype)}')
        else:
            head.append(f'FUNCTION_BLOCK "{name}"')
        head.append("{ S7_Optimized_Access := 'TRUE' }")
        head.append(f"VERSION : {version}")
        # the block's documentation comment: inside the block, as // lines after VERSION, where
        # TIA's own source export writes a block comment (our reading of its exports)
        doc = "\n".join(before)
        doc = re.sub(r"\(\*|\*\)", "", doc).strip("\n")
        head += [("// " + x).rstrip() for x in doc.split("\n")] if doc.strip() else []
        sections = {}          # header -> lines, filled in source order (comments in place)
        for blk in n.blocks:
            header, lines = self.var_block(blk)
            sections.setdefault(header, []).extend(lines)
        self.used_enums |= {self.enum_type(d.type) for b in n.blocks for d in b.decls} - {None}
        body_out = self.out = []
        temp_inits = []
        if self.is_fn:
            for blk in n.blocks:
                if blk.kind == "VAR" and "CONSTANT" not in blk.quals:
                    for d in blk.decls:
                        for nm, _ in d.names:
                            temp_inits.append(f"    #{self.locals[nm]} := {self.temp_init(d)};")
        if temp_inits:
            body_out.append("    // IEC initialises a function's locals on every call; TIA's "
                            "VAR_TEMP is not")
            body_out.extend(temp_inits)
        self.stmts(n.body, "    ", top=True)
        self.flush_comments(n.end_pos[0], "    ")
        self.close_region("    ")
        for infix, status, prev in lgf:
            body_out.extend(self.status_region(infix, status, prev))
            sections.setdefault("VAR_OUTPUT", []).append(
                f"      {status} : Word := WORD#16#7000;  // LGF-style status, derived from "
                f"x{infix}Busy, x{infix}Error, e{infix}ErrorId (docs/wiring-s7.md)")
            sections.setdefault("VAR", []).append(
                f"      {prev} : Bool;  // x{infix}Busy in the previous call (status 16#7001 on "
                "the first busy call)")
        for et in sorted(self.used_enums):
            consts = sections.setdefault("VAR CONSTANT", [])
            consts.append(f"      // {self.lib.names.get(et, et)} (an enumeration in st_lib: "
                          "here Int constants with the same numbers)")
            for item, v in self.lib.enums[et]:
                consts.append(f"      {item} : Int := {v};")
        decl_out = []
        order = ["VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR RETAIN", "VAR NON_RETAIN",
                 "VAR_TEMP", "VAR CONSTANT"]
        for header in sorted(sections, key=lambda h: order.index(h) if h in order else len(order)):
            decl_out += [f"   {header}"] + sections[header] + ["   END_VAR"]
        return head + decl_out + ["", "BEGIN"] + body_out + [
            "END_FUNCTION" if self.is_fn else "END_FUNCTION_BLOCK", ""]

    def temp_init(self, d):
        if d.init is not None:
            return self.init(d.init, self.enum_type(d.type))
        t = self.type_ref(d.type)
        zero = {"Bool": "FALSE", "Real": "0.0", "LReal": "0.0", "Time": "T#0s", "LTime": "LTIME#0s"}
        if t in zero:
            return zero[t]
        if t in ("Byte", "Word", "DWord", "LWord"):
            return f"{t.upper()}#16#0"
        if t in ELEMENTARY.values():
            return "0"
        raise _error(f"{self.g.fname}:{d.pos[0]}:{d.pos[1]}", "G0104", "a FUNCTION's VAR of type "
                     f"{t} has no SCL initialisation in the generator")

    def var_block(self, blk):
        kind = blk.kind
        if self.is_fn and kind == "VAR" and "CONSTANT" not in blk.quals:
            kind = "VAR_TEMP"      # a TIA FC has no static data
        header = " ".join([kind] + list(blk.quals))
        self.out = []
        self.flush_comments(blk.pos[0], "      ")
        for d in blk.decls:
            self.flush_comments(d.pos[0], "      ")
            names = ", ".join(self.locals[nm] for nm, _ in d.names)
            init = ""
            if d.init is not None:
                init = " := " + self.init(d.init, self.enum_type(d.type))
            if d.location is not None:
                raise _error(f"{self.g.fname}:{d.pos[0]}:{d.pos[1]}", "G0105", "located variables "
                             "(AT %...) have no SCL form in the generator")
            self.out.append(f"      {names} : {self.type_ref(d.type)}{init};")
            self.flush_comments(d.pos[0] + 1, "      ", same_line=d.pos[0], slash=True)
        return header, self.out

    def status_region(self, infix="", status=scl_status.STATUS_NAME, prev=scl_status.STATUS_PREV):
        return scl_status.region(self.n.blocks, self.locals, infix, status, prev)


class Generator:
    def __init__(self, version, full_version=None):
        self.lib = _Lib()
        self.version = version                  # TIA's block VERSION (MAJOR.MINOR)
        self.full_version = full_version or version
        self.files = []        # (fname, text, nodes)
        self.fname = ""

    def add(self, fname, text):
        diags = Diagnostics()
        nodes = parser.parse(text, fname, diags)
        if nodes is None or diags:
            raise SclError(diags.format()[0] if diags else f"{fname}: error: cannot parse")
        self.lib.add(nodes, text)
        self.files.append((fname, text, nodes))

    def generate(self):
        """{source file name: SCL text} for each file that has a block or a PLC data type."""
        out = {}
        for fname, text, nodes in self.files:
            self.fname = fname
            comments = _comments(text)
            parts = []
            for n in nodes:
                if isinstance(n, (S.FunctionBlock, S.Function)):
                    parts.extend(_Pou(self, n, text, comments).write(self.version))
                elif isinstance(n, S.TypeDecl):
                    parts.extend(self.types(n, text, comments))
                    while comments and comments[0][0] < _end_line(n, text):
                        comments.pop(0)    # the type file's comments stay with the enums
                elif isinstance(n, S.Program):
                    raise _error(f"{fname}:{n.pos[0]}:{n.pos[1]}", "G0106", "PROGRAM has no "
                                 "TIA external source form in the generator (write an OB)")
            if parts:
                head = [f"// Generated by stc.scl_out from {os.path.basename(fname)} (library "
                        f"{self.full_version}): do not edit; st_lib/ is the one source."]
                out[fname] = "\n".join(head + parts)
        return out

    def types(self, n, text, comments):
        lines = []
        for d in n.defs:
            if not isinstance(d.spec, S.StructSpec):
                continue        # enums become constants, array names are expanded
            pou = _Pou.__new__(_Pou)
            pou.g, pou.lib, pou.lines, pou.locals, pou.out = self, self.lib, text.split("\n"), {}, []
            pou.used_enums, pou.comments = set(), []
            lines.append(f'TYPE "{self.lib.names.get(d.name, d.name)}"')
            lines.append(f"VERSION : {self.version}")
            lines.append("   STRUCT")
            for m in d.spec.members:
                init = f" := {pou.init(m.init, pou.enum_type(m.type))}" if m.init is not None else ""
                trail = "".join(f"  {t}" for ln, _c, end, t in comments
                                if ln == m.pos[0] and end == ln)
                lines.append(f"      {_spelled(pou.lines, m.pos, m.names[0][0])} : "
                             f"{pou.type_ref(m.type)}{init};{trail}")
            lines.append("   END_STRUCT;")
            lines.append("END_TYPE")
            lines.append("")
        return lines


def _end_line(n, text):
    """A line after node n (TYPE ... END_TYPE): where its END_TYPE is."""
    m = re.compile(r"\bEND_TYPE\b", re.I).search(text, sum(len(x) + 1 for x in text.split("\n")[:n.pos[0] - 1]))
    return text.count("\n", 0, m.start()) + 2 if m else n.pos[0] + 1


def block_version(version_text):
    """TIA's block version MAJOR.MINOR from the library version MAJOR.MINOR.PATCH (our choice:
    TIA's VERSION has two numbers; the patch level is in the file header)."""
    major, minor = version_text.split(".")[:2]
    return f"{int(major)}.{int(minor)}"


def tia_bytes(text):
    """The bytes of an external source as TIA Portal imports it: UTF-8, with a byte order mark
    when the text has a character outside ASCII (without one TIA reads the file in the Windows
    code page and garbles it: issue 47, reported from real imports); ASCII text as it is."""
    return ("\ufeff" + text).encode("utf-8") if not text.isascii() else text.encode("ascii")


def _parsed(paths):
    g = Generator("0.0")
    for p in paths:
        with open(p, encoding="utf-8") as f:
            g.add(p, f.read())
    return g


def array_aliases(paths):
    """{ARRAY TYPE name (upper-case): `ARRAY[lo..hi] OF ELEM` spelled out} of the ST files."""
    g = _parsed(paths)
    out = {}
    for name, spec in g.lib.arrays.items():
        dims = ", ".join(f"{lo}..{hi}" for lo, hi in spec.dims)
        elem = spec.elem.name if isinstance(spec.elem, S.NamedType) else None
        if elem is not None and all(isinstance(b, int) for d in spec.dims for b in d):
            out[name] = f"ARRAY[{dims}] OF {elem}"
    return out


def library_version(paths):
    """MAJOR.MINOR.PATCH from the constants uMajor, uMinor, uPatch of the FUNCTION that declares
    them (st_lib/core/MIP_Version.st, the library's one source of its version)."""
    for _f, _t, nodes in _parsed(paths).files:
        for n in nodes:
            if not isinstance(n, S.Function):
                continue
            consts = {nm: d.init for b in n.blocks if "CONSTANT" in b.quals
                      for d in b.decls for nm, _ in d.names}
            parts = [consts.get(k) for k in ("UMAJOR", "UMINOR", "UPATCH")]
            if all(isinstance(x, S.IntLit) for x in parts):
                return ".".join(str(x.value) for x in parts)
    raise _error("stc.scl_out", "G0107", "no FUNCTION with constants uMajor, uMinor, uPatch "
                 "(st_lib/core/MIP_Version.st) among the inputs")


def generate_files(paths, version):
    """{path: SCL text} of the ST files in paths (import order)."""
    g = Generator(block_version(version), version)
    for p in paths:
        with open(p, encoding="utf-8") as f:
            g.add(p, f.read())
    return g.generate()


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m stc.scl_out",
                                 description="ST (st_lib) -> TIA Portal SCL external sources")
    ap.add_argument("-o", dest="outdir", required=True)
    ap.add_argument("--version", dest="libversion",
                    help="library version MAJOR.MINOR.PATCH (block VERSION: MAJOR.MINOR); "
                         "default: the constants uMajor, uMinor, uPatch in the inputs")
    ap.add_argument("files", nargs="+", metavar="FILE.st")
    a = ap.parse_args(argv)

    def convert():
        out = generate_files(a.files, a.libversion or library_version(a.files))
        os.makedirs(a.outdir, exist_ok=True)
        for p, text in out.items():
            dst = os.path.join(a.outdir, os.path.splitext(os.path.basename(p))[0] + ".scl")
            with open(dst, "wb") as f:
                f.write(tia_bytes(text))
    return oneline.run("stc.scl_out", convert, located=(SclError,))


if __name__ == "__main__":
    sys.exit(main())
