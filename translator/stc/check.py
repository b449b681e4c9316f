"""Semantic analysis: declarations, IEC strict typing, and the matiec dialect's restrictions.

The checker annotates expressions with `.ty` and collects everything the code generator needs in
a `Project`. Every error goes to the diagnostics with its position; analysis goes on after an
error so that one run reports as much as it can."""
import re

from . import syntax as S
from . import types as T
from .diag import CompileError

_IDENT_RE = re.compile(r"^[A-Z_][A-Z0-9_]*$")
# macros of <stdint.h>/<string.h> that an upper-case IEC name would collide with in the C output
_C_MACROS = re.compile(r"^(U?INT(8|16|32|64|MAX|PTR)_(MIN|MAX|C)|U?INT_(LEAST|FAST)(8|16|32|64)_(MIN|MAX)"
                       r"|SIZE_MAX|PTRDIFF_(MIN|MAX)|SIG_ATOMIC_(MIN|MAX)|WCHAR_(MIN|MAX)|WINT_(MIN|MAX)"
                       r"|NULL|STC_[A-Z0-9_]*)$")


class Var:
    __slots__ = ("name", "kind", "type", "init", "constant", "retain", "location", "pos",
                 "file", "cname", "glob", "owner")

    def __init__(self, name, kind, type_, init, pos, file):
        self.name, self.kind, self.type, self.init, self.pos, self.file = name, kind, type_, init, pos, file
        self.constant = self.retain = False
        self.location = None       # (area, size, parts) for located variables
        self.cname = None          # C name of located pointer / global
        self.glob = None           # for VAR_EXTERNAL: the bound Var (VAR_GLOBAL)
        self.owner = None          # owning Pou / configuration / resource


class Pou:
    def __init__(self, kind, name, node, file):
        self.kind = kind           # function function_block program
        self.name = name
        self.node = node
        self.file = file
        self.vars = {}             # NAME -> Var, declaration order
        self.rtype = None
        self.std = None            # StdFB for standard function blocks
        self.used_now = False


class Task:
    def __init__(self, name, interval_ns, priority, pos):
        self.name, self.interval_ns, self.priority, self.pos = name, interval_ns, priority, pos


class Instance:
    def __init__(self, name, pou, task, resource):
        self.name, self.pou, self.task, self.resource = name, pou, task, resource


class ResourceInfo:
    def __init__(self, name):
        self.name = name
        self.globals = {}
        self.tasks = []
        self.instances = []


class ConfigInfo:
    def __init__(self, name):
        self.name = name
        self.globals = {}
        self.resources = []


class Project:
    def __init__(self):
        self.types = {}            # NAME -> Type (named types in declaration order)
        self.type_files = {}
        self.pous = {}             # NAME -> Pou, declaration order
        self.std_pous = {}         # standard FBs in use
        self.config = None
        self.located = []          # Var of every located variable, in declaration order
        self.enum_values = {}      # VALUE -> [EnumT] for bare enum names
        self.semantics = "matiec"  # "matiec", "openplc" or "iec": run-time values the C reproduces
        # (file, (line, col), kind, text): every construct on the divergence list (matiec,
        # OpenPLC's fork and IEC may give other values), warned or not: stc --divergences
        self.divergences = []


_KIND_OK = {
    "function": {"VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR_TEMP"},
    "function_block": {"VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR_TEMP", "VAR_EXTERNAL"},
    "program": {"VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR", "VAR_TEMP", "VAR_EXTERNAL"},
}


def _lit_fits(value, ty):
    r = ty.range()
    if r is None:
        return True
    return r[0] <= value <= r[1]


class Checker:
    def __init__(self, diags, semantics="matiec", strict_iec=False):
        self.d = diags
        self.p = Project()
        self.p.semantics = semantics
        self.strict_iec = strict_iec   # --strict-iec: warn where an edition-2 checker is stricter
        self.file = None
        self.scl_files = set()         # files read as TIA SCL (compiler.py, scl_in.name_arrays)
        self.vendor_files = set()      # files in the TwinCAT / CODESYS dialect (vendor_in.py)

    def _vendor(self):
        return self.file in self.vendor_files

    def warn(self, pos, msg):
        """Portability warning: the construct's value differs between matiec and IEC."""
        self.d.warn(self.file, pos, msg)
        self.note(pos, "warned", msg.replace("portability: ", "", 1))

    def note(self, pos, kind, text):
        """A construct on the divergence list (stc --divergences lists them)."""
        self.p.divergences.append((self.file, pos, kind, text))

    # ---- errors
    def err(self, pos, msg, file=None):
        self.d.error(file or self.file, pos, msg)

    def fail(self, pos, msg):
        self.err(pos, msg)
        raise CompileError(msg)

    # ---- entry
    def run(self, files):
        """files: [(filename, [top-level nodes])]"""
        # pass 1: names of types and POUs, so declaration order does not matter
        for fname, nodes in files:
            self.file = fname
            for n in nodes:
                if isinstance(n, S.TypeDecl):
                    for td in n.defs:
                        self._declare_name(td.name, td.pos, "type")
                        self.p.types[td.name] = None
                        self.p.type_files[td.name] = (fname, td)
                elif isinstance(n, (S.Function, S.FunctionBlock, S.Program)):
                    kind = {S.Function: "function", S.FunctionBlock: "function_block",
                            S.Program: "program"}[type(n)]
                    if self._declare_name(n.name, n.pos, kind):
                        self.p.pous[n.name] = Pou(kind, n.name, n, fname)
                elif isinstance(n, S.StrayVarBlock):
                    self.err(n.pos, f"{n.block.kind} outside a POU: global variables belong in a "
                             "CONFIGURATION or RESOURCE")
        # pass 2: resolve named types
        self._resolving = set()
        for name in list(self.p.types):
            self._resolve_named(name)
        # pass 3: POU interfaces
        for pou in self.p.pous.values():
            self.file = pou.file
            self._declare_pou(pou)
        # configuration (binds globals, needed before bodies for VAR_EXTERNAL)
        configs = [(f, n) for f, nodes in files for n in nodes if isinstance(n, S.Configuration)]
        for i, (fname, c) in enumerate(configs):
            self.file = fname
            if i > 0:
                self.err(c.pos, "only one CONFIGURATION per build is supported")
                continue
            self._configuration(c)
        # bind externals
        for pou in self.p.pous.values():
            self.file = pou.file
            for v in pou.vars.values():
                if v.kind == "VAR_EXTERNAL":
                    self._bind_external(v)
        # pass 4: bodies
        for pou in self.p.pous.values():
            self.file = pou.file
            self._body(pou)
        self._check_located()
        return self.p

    _SEEN_KINDS = {}

    def _declare_name(self, name, pos, kind):
        self._check_ident(name, pos)
        if name in self.p.types or name in self.p.pous:
            self.err(pos, f"'{name}' is declared twice")
            return False
        if name in T.STD_FBS or name in T.ELEMENTARY or _conversion(name):
            self.err(pos, f"'{name}' is a standard library name and cannot be redeclared")
            return False
        return True

    def _check_ident(self, name, pos, member=False):
        if member and name in _MEMBER_OK:
            return
        if "__" in name:
            self.err(pos, f"identifier '{name}' contains '__', which matiec rejects: use a single '_'")
        elif name.endswith("_"):
            self.err(pos, f"identifier '{name}' ends with '_', which matiec rejects")
        elif _C_MACROS.match(name):
            self.err(pos, f"identifier '{name}' is a C macro name in the generated code: rename it")
        elif name in T.RESERVED or name in _keywords() or _conversion(name):
            self.err(pos, f"'{name}' is a reserved or standard library name in matiec and cannot "
                     "be used as an identifier")

    # ---- types
    def _resolve_named(self, name):
        t = self.p.types.get(name)
        if t is not None:
            return t
        fname, td = self.p.type_files[name]
        if name in self._resolving:
            self.err(td.pos, f"type '{name}' is defined in terms of itself", fname)
            return T.INT
        self._resolving.add(name)
        old = self.file
        self.file = fname
        try:
            t = self._type_def(td)
        except CompileError:
            t = T.INT
        finally:
            self.file = old
            self._resolving.discard(name)
        self.p.types[name] = t
        return t

    def _type_def(self, td):
        spec = td.spec
        if isinstance(spec, S.EnumSpec):
            vals, codes = [], []
            explicit = False
            for vname, vval, vpos in spec.items:
                if vval is not None and not self._vendor():
                    self.err(vpos, "enumerated values with explicit values (A := 0) are not "
                             "portable (matiec rejects them): declare (A, B, ...) and convert "
                             "with CASE")
                self._check_ident(vname, vpos)
                if vname in vals:
                    self.err(vpos, f"enumerated value '{vname}' is declared twice")
                # the vendor dialects: A := n, and the next one without a value is n + 1
                code = vval if vval is not None else (codes[-1] + 1 if codes else 0)
                explicit = explicit or vval is not None
                if code in codes:
                    self.err(vpos, f"enumerated value '{vname}' = {code} repeats another's value")
                vals.append(vname)
                codes.append(code)
            t = T.EnumT(td.name, vals, codes=codes if explicit else None)
            if spec.default is not None:
                if spec.default not in vals:
                    self.err(spec.pos, f"'{spec.default}' is not a value of {td.name}")
                else:
                    t.default = spec.default
            for v in vals:
                self.p.enum_values.setdefault(v, []).append(t)
            return t
        if isinstance(spec, S.StructSpec):
            fields = {}
            for m in spec.members:
                for mname, mpos in m.names:
                    self._check_ident(mname, mpos, member=True)
                    mt = self.resolve_type(m.type, member=True)
                    if mname in fields:
                        self.err(mpos, f"member '{mname}' is declared twice")
                    fields[mname] = (mt, m.init, mpos)
            t = T.StructT(td.name, fields)
            for mname, (mt, minit, mpos) in fields.items():
                if minit is not None:
                    self.check_init(minit, mt)
            return t
        base = self.resolve_type(spec, member=True)
        if base.is_array:
            t = T.ArrayT(base.elem, base.dims, td.name)
        elif base.is_elem:
            t = base.with_default(None)
        elif base.is_fb:
            self.fail(td.pos, "a TYPE cannot be an alias of a function block")
        else:
            t = base   # alias of a struct or enum: same type
        if td.init is not None:
            self.check_init(td.init, t)
            if t is base:
                self.err(td.pos, "an initial value on an alias of a STRUCT or enumerated type is "
                         "not supported: put it on the variables")
            else:
                t.default = td.init
        return t

    def resolve_type(self, spec, member=False, in_array=False):
        if isinstance(spec, S.PointerRef):
            if spec.word != "POINTER" or not self._vendor():
                self.fail(spec.pos, f"{spec.word} TO is not portable (matiec rejects pointers and "
                          "references); pointers are read in the TwinCAT / CODESYS dialects only "
                          "(--dialect=twincat|codesys)" if spec.word == "POINTER" else
                          f"unexpected '{spec.word} TO'")
            target = self.resolve_type(spec.target, member=True)
            if target.is_array and not target.name or target.is_fb:
                self.fail(spec.pos, "POINTER TO an anonymous ARRAY or a function block is not "
                          "supported: declare an array TYPE")
            return T.PointerT(target)
        if isinstance(spec, S.NamedType):
            n = spec.name
            if n == "PVOID" and self._vendor():
                return T.PointerT(T.ELEMENTARY["BYTE"])
            if n in T.ELEMENTARY:
                return T.ELEMENTARY[n]
            if n in self.p.types:
                return self._resolve_named(n)
            if n in T.STD_FBS:
                if member:
                    self.fail(spec.pos, f"a function block ({n}) cannot be a STRUCT member or "
                              "array element (matiec rejects it): declare the instances as "
                              "separate variables")
                return self._std_fb_type(n)
            if n in self.p.pous:
                pou = self.p.pous[n]
                if pou.kind != "function_block":
                    self.fail(spec.pos, f"'{n}' is a {pou.kind.replace('_', ' ')}, not a type")
                if member:
                    self.fail(spec.pos, f"a function block ({n}) cannot be a STRUCT member or "
                              "array element (matiec rejects it): declare the instances as "
                              "separate variables")
                return T.FBT(n, pou)
            if n in T.UNSUPPORTED_TYPES:
                self.fail(spec.pos, f"type {n} is not supported by stc")
            self.fail(spec.pos, f"unknown type '{n}'")
        if isinstance(spec, S.ArraySpec):
            dims = []
            for lo, hi in spec.dims:
                if lo is None or hi is None:
                    self.fail(spec.pos, "invalid integer in array bounds")
                if isinstance(lo, S.ConstBound) or isinstance(hi, S.ConstBound):
                    b = lo if isinstance(lo, S.ConstBound) else hi
                    self.fail(b.pos, "array bounds from a named constant are not portable "
                              "(matiec rejects them): write the number")
                if hi < lo:
                    self.fail(spec.pos, f"array range {lo}..{hi} is empty")
                dims.append((lo, hi))
            if isinstance(spec.elem, S.ArraySpec):
                self.fail(spec.elem.pos, "ARRAY OF ARRAY is not portable (matiec rejects it): "
                          "use a multi-dimensional array ARRAY[a..b, c..d] OF ...")
            elem = self.resolve_type(spec.elem, member=True, in_array=True)
            if elem.is_array:
                self.fail(spec.elem.pos, "ARRAY OF an array type is not portable (matiec rejects "
                          "it): use a multi-dimensional array ARRAY[a..b, c..d] OF ...")
            n = 1
            for lo, hi in dims:
                n *= hi - lo + 1
            if n > 1 << 24:
                self.fail(spec.pos, "array too large")
            return T.ArrayT(elem, dims)
        if isinstance(spec, S.SubrangeRef):
            self.fail(spec.pos, f"subrange types like {spec.base}(0..100) are not portable "
                      f"(matiec rejects them): use plain {spec.base} and LIMIT()")
        if isinstance(spec, S.StringRef):
            if self._vendor() and spec.base == "STRING" and 0 < int(spec.size) <= T.STR_MAX:
                return T.STRING       # STRING(15) of the vendor blocks: stc's STRING holds it
            self.fail(spec.pos, f"{spec.base}[{spec.size}] is not portable (matiec drops or "
                      "crashes on it): use an ARRAY OF BYTE")
        if isinstance(spec, S.StructSpec):
            self.fail(spec.pos, "an inline STRUCT in a variable declaration is not supported: "
                      "declare it in a TYPE")
        if isinstance(spec, S.EnumSpec):
            self.fail(spec.pos, "an inline enumeration in a variable declaration is not "
                      "supported: declare it in a TYPE")
        self.fail(getattr(spec, "pos", (0, 0)), "unsupported type")

    def _std_fb_type(self, name):
        pou = self.p.std_pous.get(name)
        if pou is None:
            std = T.STD_FBS[name]
            pou = Pou("function_block", name, None, None)
            pou.std = std
            for vn, tn in std.inputs:
                pou.vars[vn] = Var(vn, "VAR_INPUT", T.ELEMENTARY[tn], None, None, None)
            for vn, tn in std.outputs:
                pou.vars[vn] = Var(vn, "VAR_OUTPUT", T.ELEMENTARY[tn], None, None, None)
            self.p.std_pous[name] = pou
        return T.FBT(name, pou)

    # ---- initial values
    def check_init(self, init, ty):
        try:
            if isinstance(init, S.ArrayInit):
                if not ty.is_array:
                    self.fail(init.pos, f"an array initialiser [...] needs an ARRAY, not {ty}")
                n = 0
                for count, val in init.items:
                    if count is not None and count <= 0:
                        self.err(init.pos, "repetition count must be positive")
                        continue
                    n += count if count is not None else 1
                    if val is not None:
                        self.check_init(val, ty.elem)
                if n > ty.count():
                    self.err(init.pos, f"{n} initial values for an array of {ty.count()} elements")
            elif isinstance(init, S.StructInit):
                if not ty.is_struct:
                    self.fail(init.pos, f"a structure initialiser (a := ...) needs a STRUCT, not {ty}")
                for name, val, pos in init.items:
                    if name not in ty.fields:
                        self.err(pos, f"{ty.name} has no member '{name}'")
                        continue
                    self.check_init(val, ty.fields[name][0])
            else:
                if ty.is_array or ty.is_struct or ty.is_fb:
                    self.fail(init.pos, f"initial value of {ty} must be a "
                              + ("[...] list" if ty.is_array else "(member := ...) list"
                                 if ty.is_struct else "nothing"))
                self.scope = {}
                self.cur = None
                t = self.expr(init, ty)
                self.coerce(init, t, ty, "initial value")
                if not self.is_constant(init):
                    self.err(init.pos, "initial values must be constant expressions")
        except CompileError:
            pass

    def is_constant(self, e):
        if isinstance(e, (S.IntLit, S.RealLit, S.TimeLit, S.BoolLit, S.TypedLit, S.StringLit)):
            return True
        if isinstance(e, S.Paren):
            return self.is_constant(e.inner)
        if isinstance(e, S.UnOp):
            return self.is_constant(e.operand)
        if isinstance(e, S.BinOp):
            return self.is_constant(e.left) and self.is_constant(e.right)
        if isinstance(e, S.Name):
            return getattr(e, "enum_value", None) is not None or isinstance(e.ty, T.EnumT) and e.name not in self.scope
        if isinstance(e, S.Field):
            return getattr(e, "enum_value", None) is not None    # Enum.Value (vendor dialects)
        if isinstance(e, S.Call):
            return _conversion(e.name) is not None and all(
                self.is_constant(a.value) for a in e.args if isinstance(a, S.ArgPos))
        return False

    # ---- POU declarations
    def _declare_pou(self, pou):
        n = pou.node
        if isinstance(n, S.Function):
            try:
                pou.rtype = self.resolve_type(n.rtype)
            except CompileError:
                pou.rtype = T.INT
            if pou.rtype.is_fb:
                self.err(n.rtype.pos, "a FUNCTION cannot return a function block")
            elif pou.rtype.is_struct:
                self.err(n.rtype.pos, "a FUNCTION returning a STRUCT is not supported by stc: "
                         "use a VAR_IN_OUT or a FUNCTION_BLOCK")
            elif pou.rtype.is_array and pou.rtype.name is None:
                self.err(n.rtype.pos, "a FUNCTION returning an anonymous ARRAY cannot be "
                         "assigned anywhere (matiec rejects assigning anonymous ARRAY types): "
                         "declare a named array TYPE and return that")
        for blk in n.blocks:
            self._var_block(pou, blk)

    def _var_block(self, pou, blk, where=None):
        kind = blk.kind
        allowed = _KIND_OK[pou.kind] if pou is not None else {"VAR_GLOBAL"}
        if kind not in allowed:
            if kind == "VAR_GLOBAL":
                self.err(blk.pos, f"VAR_GLOBAL is not allowed in a {pou.kind.replace('_', ' ').upper()}: "
                         "declare it in the CONFIGURATION or RESOURCE and use VAR_EXTERNAL")
            elif kind == "VAR_EXTERNAL":
                self.err(blk.pos, "VAR_EXTERNAL is not allowed in a FUNCTION: pass the value as "
                         "VAR_INPUT or VAR_IN_OUT")
            else:
                self.err(blk.pos, f"{kind} is not allowed here")
            return
        constant = "CONSTANT" in blk.quals
        retain = "RETAIN" in blk.quals
        if len(blk.quals) > 1:
            self.err(blk.pos, f"{kind} {' '.join(blk.quals)}: one qualifier per block is "
                     "portable (matiec rejects more)")
        elif blk.quals and blk.quals[0] != "CONSTANT" and (
                kind not in ("VAR", "VAR_INPUT", "VAR_OUTPUT", "VAR_GLOBAL")
                or (pou is not None and pou.kind == "function")):
            where_ = "in a FUNCTION" if pou is not None and pou.kind == "function" else f"on {kind}"
            self.err(blk.pos, f"{blk.quals[0]} is not allowed {where_} (matiec rejects it)")
        elif blk.quals == ["NON_RETAIN"] and kind == "VAR_GLOBAL":
            self.err(blk.pos, "NON_RETAIN is not allowed on VAR_GLOBAL (matiec rejects it): "
                     "a VAR_GLOBAL without a qualifier is not retained")
        if constant and kind not in ("VAR", "VAR_GLOBAL", "VAR_EXTERNAL"):
            self.err(blk.pos, f"CONSTANT is not allowed on {kind}")
        located = [d for d in blk.decls if d.location is not None]
        if located and len(located) != len(blk.decls):
            self.err(blk.pos, "located and unlocated variables in one VAR block are not portable "
                     "(matiec rejects it): put the AT variables in a VAR block of their own")
        target = pou.vars if pou is not None else where
        for d in blk.decls:
            try:
                ty = self.resolve_type(d.type)
            except CompileError:
                continue
            if not d.names:
                self.err(d.pos, "a located variable needs a name (matiec rejects 'AT %... :' "
                         "without one)")
                continue
            for name, npos in d.names:
                self._check_ident(name, npos)
                if name in target:
                    self.err(npos, f"'{name}' is declared twice")
                    continue
                if pou is not None and name == pou.name:
                    self.err(npos, f"'{name}' is the name of the POU")
                if name in self.p.pous:
                    self.err(npos, f"'{name}' is already the name of a POU")
                v = Var(name, kind, ty, d.init, npos, self.file)
                v.constant, v.retain, v.owner = constant, retain, pou
                if ty.is_fb:
                    if pou is not None and pou.kind == "function":
                        self.err(npos, "a function block instance inside a FUNCTION is not "
                                 "portable (matiec rejects it): use a FUNCTION_BLOCK")
                    if kind == "VAR_IN_OUT" and not self._vendor():
                        self.err(npos, "VAR_IN_OUT of a function block type is not portable "
                                 "(it crashes matiec)")
                    if kind in ("VAR_INPUT", "VAR_OUTPUT") and pou is not None and pou.kind == "function":
                        self.err(npos, "a function block cannot be a FUNCTION parameter")
                    if constant:
                        self.err(npos, "a function block instance cannot be CONSTANT")
                if d.location is not None:
                    self._located(v, d.location, pou)
                if d.init is not None:
                    if kind == "VAR_IN_OUT" or kind == "VAR_EXTERNAL":
                        self.err(d.init.pos, f"{kind} variables cannot have an initial value")
                    elif ty.is_fb:
                        self.err(d.init.pos, "function block instances cannot have an initial value")
                    else:
                        self.check_init(d.init, ty)
                if constant and d.init is None and kind != "VAR_EXTERNAL":
                    self.err(npos, f"CONSTANT '{name}' needs an initial value")
                if (pou is not None and pou.kind == "function" and kind == "VAR_INPUT"
                        and ty.is_array):
                    self.err(npos, "a FUNCTION with an array VAR_INPUT compiles with matiec but "
                             "its C does not: use VAR_IN_OUT")
                target[name] = v

    _LOC_RE = re.compile(r"^%([IQM])([XBWDL]?)([0-9]+(?:\.[0-9]+)*)$")
    _SIZE = {"X": 1, "B": 8, "W": 16, "D": 32, "L": 64}

    def _located(self, v, loc, pou):
        text, pos = loc
        vendor_fb = pou is not None and pou.kind == "function_block" and self._vendor()
        if pou is not None and pou.kind != "program" and not vendor_fb:
            # (the vendor dialects: TwinCAT links an FB's AT %I* / %Q* in its I/O mapping; stc
            # takes full addresses there, one cell for every instance: the stand-ins' channel)
            self.err(pos, f"located variables in a {pou.kind.upper()} are not "
                     "portable (matiec rejects them): declare them in the PROGRAM and pass them "
                     "as inputs/outputs")
            return
        if "*" in text:
            self.err(pos, "'AT %I*' is not portable (matiec rejects it): give the full address")
            return
        m = self._LOC_RE.match(text)
        if not m:
            self.err(pos, f"invalid direct address {text}")
            return
        area, size, addr = m.group(1), m.group(2) or "X", m.group(3)
        parts = [int(x) for x in addr.split(".")]
        if v.type.is_array:
            self.err(pos, "a located ARRAY is not portable (matiec rejects it): declare one "
                     "located variable per address")
            return
        if not v.type.is_elem or v.type.kind in ("time", "real") and size in ("X", "B", "W"):
            if not v.type.is_elem:
                self.err(pos, f"a located variable must be of an elementary type, not {v.type}")
                return
        if v.type.is_elem and v.type.kind != "time":
            bits = v.type.bits
            if (size == "X") != (bits == 1) or size != "X" and self._SIZE[size] != bits:
                self.err(pos, f"{v.type} does not fit address {text} ({self._SIZE[size]} bit)")
                return
        elif v.type.kind == "time":
            self.err(pos, "a located TIME variable is not supported")
            return
        if size == "X" and len(parts) != 2:
            self.err(pos, f"a bit address needs byte.bit, like %{area}X0.0")
            return
        if size != "X" and len(parts) != 1:
            self.err(pos, f"invalid direct address {text}")
            return
        if size == "X" and not 0 <= parts[1] <= 7:
            self.warn(pos, f"portability: bit number {parts[1]} is outside 0..7: matiec accepts "
                      "it, but OpenPLC's I/O image has 8 bits per byte, so nothing reaches it")
        v.location = (area, size, parts)
        v.cname = "__" + area + size + "_".join(str(x) for x in parts)
        v.pos = v.pos
        self.p.located.append(v)

    def _check_located(self):
        seen = {}
        for v in self.p.located:
            if v.cname in seen:
                first = seen[v.cname]
                self.err(v.pos, f"address {_addr_text(v)} is already used by '{first.name}' "
                         f"({first.file}:{first.pos[0]}): matiec rejects an address used twice",
                         v.file)
            else:
                seen[v.cname] = v

    # ---- configuration
    def _configuration(self, c):
        cfg = ConfigInfo(c.name)
        self.p.config = cfg
        self._check_ident(c.name, c.pos)
        for blk in c.blocks:
            self._global_block(blk, cfg.globals, cfg.name)
        resources = list(c.resources)
        if c.tasks or c.progs:
            if resources:
                self.err(c.pos, "tasks and programs belong inside the RESOURCE")
            else:
                # single resource configuration
                resources = [S.Resource(c.pos, "RESOURCE1", "PLC", [], c.tasks, c.progs)]
        if not resources:
            self.err(c.pos, f"CONFIGURATION {c.name} has no RESOURCE")
        names = set()
        for r in resources:
            ri = ResourceInfo(r.name)
            if r.name in self.p.pous or r.name in self.p.types:
                self.err(r.pos, f"resource '{r.name}' has the name of a POU or type")
            if r.name in names:
                self.err(r.pos, f"resource '{r.name}' is declared twice")
            names.add(r.name)
            self._check_ident(r.name, r.pos)
            cfg.resources.append(ri)
            for blk in r.blocks:
                self._global_block(blk, ri.globals, f"{cfg.name}.{ri.name}")
            tasks = {}
            for t in r.tasks:
                self._check_ident(t.name, t.pos)
                interval, prio = None, 0
                for pn, pv, ppos in t.params:
                    if pn == "INTERVAL":
                        self.scope, self.cur = {}, None
                        try:
                            ty = self.expr(pv, T.TIME)
                            if not (ty.is_elem and ty.kind == "time") or not isinstance(pv, S.TimeLit):
                                self.fail(pv.pos, "INTERVAL must be a TIME literal like T#20ms")
                            interval = pv.ns
                        except CompileError:
                            pass
                    elif pn == "PRIORITY":
                        if not isinstance(pv, S.IntLit):
                            self.err(pv.pos, "PRIORITY must be an integer")
                        else:
                            prio = pv.value
                    elif pn == "SINGLE":
                        self.err(ppos, "SINGLE (event) tasks are not supported by stc: use INTERVAL")
                    else:
                        self.err(ppos, f"unknown task parameter '{pn}'")
                if not any(pn == "PRIORITY" for pn, _, _ in t.params):
                    self.err(t.pos, f"task {t.name} needs PRIORITY := n (matiec rejects a TASK "
                             "without it)")
                if interval is not None and interval <= 0:
                    self.err(t.pos, "task INTERVAL must be positive")
                    interval = None
                if interval is None and not any(pn == "SINGLE" for pn, _, _ in t.params):
                    self.err(t.pos, f"task {t.name} needs INTERVAL := T#...")
                if t.name in tasks:
                    self.err(t.pos, f"task '{t.name}' is declared twice")
                task = Task(t.name, interval or 1, prio, t.pos)
                tasks[t.name] = task
                ri.tasks.append(task)
            inames = set()
            for pc in r.progs:
                self._check_ident(pc.name, pc.pos)
                if pc.name in inames:
                    self.err(pc.pos, f"program instance '{pc.name}' is declared twice")
                inames.add(pc.name)
                pou = self.p.pous.get(pc.type)
                if pou is None or pou.kind != "program":
                    self.err(pc.pos, f"'{pc.type}' is not a PROGRAM")
                    continue
                if pc.args:
                    self.err(pc.pos, "program instance arguments are not supported by stc: use "
                             "VAR_GLOBAL and VAR_EXTERNAL")
                task = None
                if pc.task is not None:
                    task = tasks.get(pc.task)
                    if task is None:
                        self.err(pc.pos, f"unknown task '{pc.task}'")
                ri.instances.append(Instance(pc.name, pou, task, ri))

    def _global_block(self, blk, target, owner):
        if blk.kind != "VAR_GLOBAL":
            self.err(blk.pos, f"{blk.kind} is not allowed in a CONFIGURATION or RESOURCE: use VAR_GLOBAL")
            return
        before = set(target)
        self._var_block(None, blk, target)
        for name, v in target.items():
            if name in before:
                continue
            v.owner = owner
            if v.type.is_fb:
                self.err(v.pos, "a function block instance as VAR_GLOBAL is not supported by stc")
            if v.location is None:
                v.cname = owner.replace(".", "__") + "__" + name

    def _bind_external(self, v):
        cands = []
        cfg = self.p.config
        if cfg is not None:
            if v.name in cfg.globals:
                cands.append(cfg.globals[v.name])
            for r in cfg.resources:
                if v.name in r.globals:
                    cands.append(r.globals[v.name])
        if not cands:
            self.err(v.pos, f"VAR_EXTERNAL '{v.name}' has no VAR_GLOBAL of that name in the "
                     "configuration")
            return
        if len(cands) > 1:
            self.err(v.pos, f"VAR_EXTERNAL '{v.name}' matches VAR_GLOBALs of several resources: "
                     "stc binds externals by name, give them distinct names")
            return
        g = cands[0]
        if not T.same_type(g.type, v.type, array_names=False):
            self.err(v.pos, f"VAR_EXTERNAL '{v.name}' is {v.type} but the VAR_GLOBAL is {g.type}")
            return
        if g.constant and not v.constant:
            self.err(v.pos, f"VAR_GLOBAL '{v.name}' is CONSTANT: declare the VAR_EXTERNAL CONSTANT too")
        v.glob = g

    # ---- bodies
    def _body(self, pou):
        self.cur = pou
        self.scope = pou.vars
        self.loop_depth = 0
        self.for_vars = []
        if not pou.node.body:
            self.err(pou.node.pos, f"a {pou.kind.replace('_', ' ').upper()} without statements is "
                     "not portable (matiec rejects it): give it at least one statement")
        self.stmts(pou.node.body)

    def stmts(self, lst):
        for s in lst:
            try:
                self.stmt(s)
            except CompileError:
                pass

    def stmt(self, s):
        if isinstance(s, S.Assign):
            tt = self.lvalue(s.target, "assign to")
            vt = self.expr(s.value, tt)
            self.coerce(s.value, vt, tt, "assignment")
        elif isinstance(s, S.CallStmt):
            self.call(s, statement=True)
            if getattr(s, "kind", "fb") == "vendor":
                pass                  # MEMCPY(...); as the vendor IDEs allow it
            elif getattr(s, "kind", "fb") != "fb":
                self.err(s.pos, "a FUNCTION call as a statement is not portable (matiec rejects "
                         "it): assign its result to a variable")
        elif isinstance(s, S.If):
            for cond, body in s.branches:
                self.cond(cond, "IF")
                if not body:
                    self.err(cond.pos, "empty THEN/ELSIF branch is not portable (matiec rejects "
                             "it): add a statement or invert the condition")
                self.stmts(body)
            if s.orelse is not None:
                if not s.orelse:
                    self.err(s.pos, "empty ELSE branch is not portable (matiec rejects it): "
                             "remove the ELSE")
                self.stmts(s.orelse)
        elif isinstance(s, S.Case):
            self.case(s)
        elif isinstance(s, S.For):
            self.for_(s)
        elif isinstance(s, S.While):
            self.cond(s.cond, "WHILE")
            if not s.body:
                self.err(s.pos, "empty WHILE body is not portable (matiec rejects it)")
            self.loop_depth += 1
            self.stmts(s.body)
            self.loop_depth -= 1
        elif isinstance(s, S.Repeat):
            if not s.body:
                self.err(s.pos, "empty REPEAT body is not portable (matiec rejects it)")
            self.loop_depth += 1
            self.stmts(s.body)
            self.loop_depth -= 1
            self.cond(s.cond, "UNTIL")
        elif isinstance(s, S.Exit):
            if not self.loop_depth:
                self.err(s.pos, "EXIT outside a loop")
        elif isinstance(s, S.Continue):
            if not self.loop_depth:
                self.err(s.pos, "CONTINUE outside a loop")
        elif isinstance(s, S.Return):
            pass
        elif isinstance(s, S.Empty):
            self.err(s.pos, "a lone ';' (empty statement) is not portable (matiec rejects it): "
                     "remove it")
        elif isinstance(s, S.CaseLabels):
            self.err(s.pos, "case label outside CASE")

    def cond(self, e, what):
        t = self.expr(e, T.BOOL)
        if not (t.is_elem and t.kind == "bool"):
            self.err(e.pos, f"{what} condition must be BOOL, not {t} (write e.g. x <> 0)")

    def case(self, s):
        st = self.expr(s.selector, None)
        if st.is_lit:
            self.settle(s.selector, T.DINT)
            st = T.DINT
        if st.is_elem and st.kind == "bit":
            self.err(s.selector.pos, f"CASE on {st} is not portable (matiec rejects it): "
                     f"convert first, e.g. CASE {st.name}_TO_UINT(x) OF")
        elif not (st.is_enum or st.is_elem and st.is_int):
            self.err(s.selector.pos, f"CASE selector must be an integer or enumerated type, not {st}")
            st = None
        else:
            # matiec's switch() sees an 8/16-bit selector expression untruncated
            self._warn_narrow(S.BinOp(s.selector.pos, "=", s.selector, s.selector), st)
        groups = []
        cur = None
        seen = []
        for item in s.items:
            if isinstance(item, S.CaseLabels):
                cur = (item, [])
                groups.append(cur)
                for lo, hi in item.labels:
                    vlo = self.case_label(lo, st)
                    vhi = self.case_label(hi, st) if hi is not None else vlo
                    if vlo is not None and vhi is not None:
                        if hi is not None and vhi < vlo:
                            self.err(lo.pos if isinstance(lo, S.Node) else item.pos,
                                     f"empty case range {vlo}..{vhi}")
                        for a, b in seen:
                            if not (vhi < a or vlo > b):
                                self.err(item.pos, "case label value already used")
                                break
                        seen.append((vlo, vhi))
            else:
                if cur is None:
                    self.err(item.pos, "statement before the first case label")
                    continue
                cur[1].append(item)
        s.groups = groups
        self.stmts([x for _, body in groups for x in body])
        for labels, body in groups:
            if not body:
                self.err(labels.pos, "empty case branch is not portable (matiec rejects it): "
                         "add a statement")
        if s.orelse is not None:
            if not s.orelse:
                self.err(s.pos, "empty ELSE branch is not portable (matiec rejects it): remove the ELSE")
            self.stmts(s.orelse)
        s.sel_type = st

    def case_label(self, lab, st):
        """Return the integer value of a case label (enum: its index)."""
        if lab is None:
            self.err(None, "invalid integer case label")
            return None
        if isinstance(lab, int):
            if st is not None and st.is_enum:
                self.err(None, "integer label in CASE on enumeration")
                return None
            if st is not None and st.is_elem and not _lit_fits(lab, st):
                self.err(None, f"case label {lab} out of range of {st}")
            return lab
        pos = lab.pos
        if isinstance(lab, S.IntLit):
            self.err(pos, f"hexadecimal/based case labels ({lab.text}) are not portable (matiec "
                     f"rejects them): write the decimal value {lab.value}")
            return None
        if isinstance(lab, S.TypedLit):
            if lab.kind == "ident":
                return self.enum_label(lab.type_name, lab.value, pos, st)
            self.err(pos, f"typed case labels ({lab.text}) are not portable (matiec rejects them): "
                     f"write the plain decimal value")
            return None
        if isinstance(lab, S.Name):
            if st is not None and st.is_enum:
                if lab.name in st.values:
                    return st.code(lab.name)
                self.err(pos, f"'{lab.name}' is not a value of {st.name}")
                return None
            self.err(pos, f"named constants as case labels ('{lab.name}') are not portable "
                     "(matiec rejects them): write the decimal value")
            return None
        return None

    def enum_label(self, tname, vname, pos, st):
        et = self.p.types.get(tname)
        if et is None or not et.is_enum:
            self.err(pos, f"'{tname}' is not an enumerated type")
            return None
        if vname not in et.values:
            self.err(pos, f"'{vname}' is not a value of {tname}")
            return None
        if st is not None and not (st.is_enum and st.name == et.name):
            self.err(pos, f"label of type {et.name} in CASE on {st}")
            return None
        return et.code(vname)

    def for_(self, s):
        v = self.lookup(s.var)
        vt = v.type
        s.var.ty = vt
        s.var.var = v
        if not (vt.is_elem and vt.is_int):
            self.err(s.var.pos, f"FOR variable must be of an integer type, not {vt}")
        if v.constant:
            self.err(s.var.pos, f"'{v.name}' is CONSTANT")
        if v.kind in ("VAR_INPUT",) and self.cur.kind == "function_block":
            pass
        for e in (s.start, s.end, s.step):
            if e is not None:
                t = self.expr(e, vt)
                self.coerce(e, t, vt, "FOR bound")
        if vt.is_elem and vt.is_int:
            self._for_wraps(s, vt)
            self._for_upstream(s)
        if not s.body:
            self.err(s.pos, "empty FOR body is not portable (matiec rejects it)")
        self.loop_depth += 1
        self.stmts(s.body)
        self.loop_depth -= 1

    def _for_upstream(self, s):
        """Upstream matiec runs no pass unless start < end (start + BY <= end with BY): a FOR
        whose bounds may be equal (start + BY past end) runs once elsewhere, never there."""
        start, end = self.const_value(s.start), self.const_value(s.end)
        step = self.const_value(s.step) if s.step is not None else 1
        if start is not None and end is not None and step is not None and step != 0:
            if step > 0 and start <= end and start + step > end or \
                    step < 0 and start >= end and start + step < end:
                self.warn(s.pos, "portability: this FOR runs once in IEC and OpenPLC's matiec "
                          "fork but zero times in upstream matiec (it needs start < end, or "
                          "start + BY within end, for the first pass)")
            return
        self.note(s.pos, "for-once", "FOR with bounds that are not constants: when they allow "
                  "exactly one pass, upstream matiec runs none")

    def _for_wraps(self, s, vt):
        """Portability warning for a FOR whose variable would step past its type's limit:
        OpenPLC's fork runs FOR as 'while i <= end: body; i += step', which wraps there and
        never ends (stc and upstream matiec stop). Constant bounds only."""
        end = self.const_value(s.end)
        step = self.const_value(s.step) if s.step is not None else 1
        start = self.const_value(s.start)
        if end is None or step is None or step == 0:
            return
        lo, hi = vt.range()
        if start is not None:
            if (step > 0 and start > end) or (step < 0 and start < end):
                return
            last = start + (end - start) // step * step
        else:
            last = end      # the last value is at most end: warn when end itself is the limit
        if (step > 0 and last + step > hi) or (step < 0 and last + step < lo):
            self.note(s.pos, "for-wrap", "FOR past the type's limit")
            self.warn(s.pos, f"portability: this FOR steps {s.var.name} past the limit of {vt} "
                      f"after its last pass: OpenPLC's matiec fork wraps it and loops forever "
                      f"(stc and upstream matiec stop); use a wider variable or EXIT")

    # ---- lookup
    def lookup(self, name_node):
        n = name_node.name
        v = self.scope.get(n)
        if v is not None:
            return v
        if self.cur is not None and self.cur.kind == "function" and n == self.cur.name:
            return self._result_var(self.cur)
        if n in ("EN", "ENO") and self.cur is not None:
            if self.cur.kind in ("function_block", "function"):
                # the instance's own EN and ENO (the body may clear ENO: the caller reads it)
                self.note(name_node.pos, "en-eno", f"{n} in a {self.cur.kind.replace('_', ' ')} body")
                imp = self.cur.__dict__.setdefault("implicit", {})
                if n not in imp:
                    imp[n] = Var(n, "VAR_INPUT" if n == "EN" else "VAR_OUTPUT", T.BOOL, None,
                                 self.cur.node.pos, self.cur.file)
                return imp[n]
            self.fail(name_node.pos, f"{n} in a PROGRAM body is not portable (matiec rejects it)")
        self.fail(name_node.pos, f"unknown variable '{n}'")

    def _result_var(self, pou):
        rv = getattr(pou, "result_var", None)
        if rv is None:
            rv = Var(pou.name, "RESULT", pou.rtype, None, pou.node.pos, pou.file)
            pou.result_var = rv
        return rv

    def lvalue(self, e, what):
        """Type of an assignable expression; rejects constants and outputs of instances."""
        if isinstance(e, S.Name):
            v = self.lookup(e)
            e.var = v
            e.ty = v.type
            if v.constant:
                self.err(e.pos, f"cannot {what} CONSTANT '{v.name}'")
            if v.kind == "VAR_INPUT" and self.cur is not None and self.cur.kind == "function":
                pass
            if v.type.is_fb:
                self.err(e.pos, f"cannot assign to function block instance '{v.name}'")
            return v.type
        if isinstance(e, S.Field):
            bt = self.expr(e.base, None, lvalue=True)
            if bt.is_fb:
                ft = self.fb_member(e, bt)
                fv = bt.pou.vars.get(e.name)
                if fv is None:
                    self.fail(e.pos, f"{e.name} of a function block instance is set by its call "
                              f"(EN := ... in the call), not by an assignment")
                if fv.kind == "VAR_OUTPUT":
                    self.err(e.pos, f"writing output {e.name} of function block instance from "
                             "outside is not portable (matiec rejects it)")
                elif fv.kind not in ("VAR_INPUT",):
                    self.err(e.pos, f"'{e.name}' is not an input of {bt.name}")
                self._check_base_assignable(e.base)
                return ft
            self._check_base_assignable(e.base)
            return self.expr(e, None)
        if isinstance(e, S.Index):
            self._check_base_assignable(e.base)
            return self.expr(e, None)
        if isinstance(e, S.BitAccess):
            return self.expr(e, None)
        if isinstance(e, S.Deref):
            return self.expr(e, None)
        self.fail(e.pos, "the left side of ':=' must be a variable")

    def _check_base_assignable(self, e):
        while isinstance(e, (S.Field, S.Index)):
            e = e.base
        if isinstance(e, S.Name):
            v = getattr(e, "var", None) or self.scope.get(e.name)
            if v is not None and v.constant:
                self.err(e.pos, f"cannot assign to CONSTANT '{v.name}'")

    def fb_member(self, e, bt):
        if e.name in ("EN", "ENO") and e.name not in bt.pou.vars:
            # every instance has EN and ENO (matiec: readable as inst.ENO after a call)
            self.note(e.pos, "en-eno", f"{e.name} of an instance")
            e.ty = T.BOOL
            return T.BOOL
        fv = bt.pou.vars.get(e.name)
        if fv is not None and fv.kind == "VAR" and bt.pou.std is None:
            e.ty = fv.type      # matiec lets a program read an instance's local variables
            return fv.type
        if fv is None or fv.kind not in ("VAR_INPUT", "VAR_OUTPUT"):
            if fv is not None and bt.pou.std is None:
                self.fail(e.pos, f"'{e.name}' of {bt.name} is not an input or output: internal "
                          "variables are not accessible from outside")
            self.fail(e.pos, f"{bt.name} has no input or output '{e.name}'")
        e.ty = fv.type
        return fv.type

    # ---- expressions
    def expr(self, e, expected, lvalue=False):
        """Type of expression e (LitT for untyped literal expressions). `expected` is a hint
        used to settle untyped literals."""
        t = self._expr(e, expected)
        e.ty = t
        if t.is_lit and expected is not None and not expected.is_lit:
            self.coerce(e, t, expected, None, soft=True)
        return t

    def _expr(self, e, expected):
        if isinstance(e, S.IntLit):
            if e.value is None:
                self.fail(e.pos, f"invalid integer literal {e.text}")
            return T.LIT_INT
        if isinstance(e, S.RealLit):
            return T.LIT_REAL
        if isinstance(e, S.BoolLit):
            return T.BOOL
        if isinstance(e, S.TimeLit):
            if e.ns is None:
                self.fail(e.pos, f"malformed TIME literal {e.text}")
            if re.search(r"[0-9](us|ns)", e.text or "", re.I):
                self.fail(e.pos, f"{e.text}: the units us and ns are not portable (matiec rejects "
                          "them): write fractions of ms, e.g. T#0.1ms")
            return T.TIME
        if isinstance(e, S.StringLit):
            if e.text.startswith('"'):
                self.fail(e.pos, "WSTRING literals (\"...\") are not supported by stc: use "
                          "'...' (STRING)")
            v = _string_value(e.text[1:-1])
            if v is None:
                self.fail(e.pos, f"invalid $ escape in string literal {e.text}")
            if len(v) > T.STR_MAX:
                self.warn(e.pos, f"string literal of {len(v)} characters: a STRING holds "
                          f"{T.STR_MAX} (matiec cuts it)")
                v = v[:T.STR_MAX]
            e.value = v
            return T.STRING
        if isinstance(e, S.TypedLit):
            return self.typed_lit(e)
        if isinstance(e, S.Paren):
            t = self.expr(e.inner, expected)
            return t
        if isinstance(e, S.Name):
            v = self.scope.get(e.name)
            if v is None and self.cur is not None and self.cur.kind == "function" and e.name == self.cur.name:
                v = self._result_var(self.cur)
            if v is None:
                ets = self.p.enum_values.get(e.name)
                if ets:
                    et = ets[0]
                    if len(ets) > 1:
                        if expected is not None and expected.is_enum and expected in ets:
                            et = expected
                        else:
                            self.fail(e.pos, f"'{e.name}' is a value of several enumerated types: "
                                      f"write {ets[0].name}#{e.name}")
                    e.enum_value = (et, et.values.index(e.name))
                    return et
                if e.name in self.p.pous or e.name in T.STD_FBS:
                    self.fail(e.pos, f"'{e.name}' is a POU, not a variable")
                self.fail(e.pos, f"unknown variable '{e.name}'")
            e.var = v
            return v.type
        if isinstance(e, S.Field):
            if isinstance(e.base, S.Name) and self._vendor() and e.base.name not in self.scope \
                    and self.p.types.get(e.base.name) is not None \
                    and self.p.types[e.base.name].is_enum:
                # Enum.Value (the vendor dialects; CODESYS's qualified_only enumerations)
                et = self.p.types[e.base.name]
                if e.name not in et.values:
                    self.fail(e.pos, f"'{e.name}' is not a value of {et.name}")
                e.enum_value = (et, et.values.index(e.name))
                return et
            bt = self.expr(e.base, None)
            if bt.is_fb:
                return self.fb_member(e, bt)
            if bt.is_struct:
                f = bt.fields.get(e.name)
                if f is None:
                    self.fail(e.pos, f"{bt.name} has no member '{e.name}'")
                return f[0]
            self.fail(e.pos, f"'.{e.name}' on a value of type {bt} (only STRUCT members and "
                      "function block outputs have fields)")
        if isinstance(e, S.Index):
            bt = self.expr(e.base, None)
            if not bt.is_array:
                self.fail(e.pos, f"indexing a value of type {bt}, which is not an ARRAY")
            if len(e.indexes) != len(bt.dims):
                self.fail(e.pos, f"{bt} needs {len(bt.dims)} index(es), got {len(e.indexes)}")
            for ix, (lo, hi) in zip(e.indexes, bt.dims):
                it = self.expr(ix, None)
                if it.is_lit:
                    if it.kind != "int":
                        self.fail(ix.pos, "array index must be an integer")
                    self.settle(ix, T.DINT)
                    v = self.const_value(ix)
                    if v is not None and not lo <= v <= hi:
                        self.err(ix.pos, f"index {v} is out of bounds {lo}..{hi}")
                elif it.is_elem and it.kind == "bit":
                    self.err(ix.pos, f"an array index of type {it} is not portable (matiec rejects "
                             f"it): convert it, e.g. {it.name}_TO_UINT(i)")
                elif not (it.is_elem and it.is_int):
                    self.err(ix.pos, f"array index must be of an integer type, not {it}")
            return bt.elem
        if isinstance(e, S.BitAccess):
            self.expr(e.base, None)
            bit = e.bit.lstrip("%XxBbWwDd") if e.bit.startswith("%") else e.bit
            self.fail(e.pos, f"bit access .{e.bit} is not portable (matiec rejects it): use "
                      f"(x AND 16#{1 << min(int(bit) if bit.isdigit() else 0, 63):X}) <> 0 to read; "
                      "OR / AND NOT masks to write")
        if isinstance(e, S.Deref):
            if not self._vendor():
                self.fail(e.pos, "pointer dereference (^) is not portable (matiec rejects POINTER TO)")
            bt = self.expr(e.base, None)
            if not isinstance(bt, T.PointerT):
                self.fail(e.pos, f"'^' on a value of type {bt}, which is not a POINTER TO")
            return bt.target
        if isinstance(e, S.Call):
            return self.call(e, statement=False, expected=expected)
        if isinstance(e, S.UnOp):
            return self.unop(e, expected)
        if isinstance(e, S.BinOp):
            return self.binop(e, expected)
        self.fail(e.pos, "unsupported expression")

    def typed_lit(self, e):
        tn = e.type_name
        if e.kind == "bad":
            self.fail(e.pos, f"invalid integer literal in {e.text}")
        if tn in self.p.types and self.p.types[tn] is not None and self.p.types[tn].is_enum:
            et = self.p.types[tn]
            if e.kind != "ident" or e.value not in et.values:
                self.fail(e.pos, f"'{e.text}': {e.value} is not a value of {tn}")
            e.enum_value = (et, et.values.index(e.value))
            return et
        if tn in ("T", "TIME"):
            self.fail(e.pos, f"malformed TIME literal {e.text}")
        t = T.ELEMENTARY.get(tn)
        if t is None or t.kind == "time":
            if tn in T.UNSUPPORTED_TYPES or tn in ("D", "TOD", "DT"):
                self.fail(e.pos, f"{tn} literals are not supported by stc")
            self.fail(e.pos, f"unknown type or enumeration '{tn}' in literal {e.text}")
        if t.kind == "bool":
            if e.kind == "bool" or e.kind == "int" and e.value in (0, 1):
                return t
            self.fail(e.pos, f"invalid BOOL literal {e.text}")
        if t.kind == "real":
            if e.kind != "real":
                self.fail(e.pos, f"invalid {tn} literal {e.text}")
            return t
        if e.kind != "int":
            self.fail(e.pos, f"invalid {tn} literal {e.text}")
        if not _lit_fits(e.value, t):
            self.fail(e.pos, f"{e.text} is out of range of {tn}")
        return t

    def unop(self, e, expected):
        t = self.expr(e.operand, expected)
        if e.op == "NOT":
            if t.is_lit:
                if t.kind != "int":
                    self.fail(e.pos, "NOT needs BOOL or a bit string type")
                return t
            if not (t.is_elem and t.is_anybit):
                self.fail(e.pos, f"NOT needs BOOL or a bit string type, not {t}")
            return t
        if t.is_lit:
            return t
        if e.op == "-":
            if t.is_elem and (t.kind in ("sint", "real", "time")):
                return t
            self.fail(e.pos, f"unary minus needs a signed type, not {t}")
        if t.is_elem and t.is_num:
            return t
        self.fail(e.pos, f"unary + needs a numeric type, not {t}")

    _ARITH = {"+", "-", "*", "/", "MOD", "**"}
    _CMP = {"=", "<>", "<", ">", "<=", ">="}
    _LOGIC = {"AND", "OR", "XOR"}

    def binop(self, e, expected):
        op = e.op
        hint = expected if op in self._ARITH or op in self._LOGIC else None
        lt = self.expr(e.left, hint)
        rt = self.expr(e.right, hint if not lt.is_lit and op in self._CMP else (lt if not lt.is_lit else hint))
        if op in self._CMP and lt.is_lit and not rt.is_lit:
            self.coerce(e.left, lt, rt, None, soft=True)
            lt = e.left.ty
        if op in self._CMP and rt.is_lit and not lt.is_lit:
            self.coerce(e.right, rt, lt, None, soft=True)
            rt = e.right.ty
        # TIME arithmetic
        if op in ("*", "/") and lt.is_elem and lt.kind == "time":
            if rt.is_lit or rt.is_elem and rt.is_num:
                if rt.is_lit:
                    self.settle(e.right, T.DINT if rt.kind == "int" else T.ELEMENTARY["LREAL"])
                self._warn_time_scale(e, e.left, e.right)
                return T.TIME
            self.fail(e.pos, f"TIME {op} {rt}: the right operand must be a number")
        if op == "*" and rt.is_elem and rt.kind == "time" and (lt.is_lit or lt.is_elem and lt.is_num):
            # matiec accepts it, but its C passes the number as the TIME argument of __time_mul
            # and does not compile (checked with iec2c): refuse it here, where the line is known
            self.fail(e.pos, "number * TIME: matiec's generated C does not compile this order; "
                      "write TIME * number")
        if op in ("+", "-") and lt.is_elem and lt.kind == "time":
            if rt.is_elem and rt.kind == "time":
                self.note(e.pos, "time-sum", f"TIME '{op}': matiec leaves a nanosecond part of "
                          "exactly 1e9 unnormalised (it compares below the whole second)")
                return T.TIME
            self.fail(e.pos, f"TIME {op} {rt}: both operands must be TIME (write e.g. T#5ms)")
        if op == "**":
            return self._power(e, lt, rt)
        if lt.is_lit and rt.is_lit:
            if op in self._CMP:
                k = "real" if "real" in (lt.kind, rt.kind) else "int"
                base = T.ELEMENTARY["LREAL"] if k == "real" else T.LINT
                self.settle(e.left, base)
                self.settle(e.right, base)
                return T.BOOL
            if op in self._LOGIC and "real" in (lt.kind, rt.kind):
                self.fail(e.pos, f"{op} needs BOOL or a bit string type")
            return T.LIT_REAL if "real" in (lt.kind, rt.kind) else T.LIT_INT
        if lt.is_lit:
            self.coerce(e.left, lt, rt, None, soft=True)
            self.range_check(e.left, rt)
            self.need_settled(e.left, rt)
            lt = rt
        elif rt.is_lit:
            self.coerce(e.right, rt, lt, None, soft=True)
            self.range_check(e.right, lt)
            self.need_settled(e.right, lt)
            rt = lt
        if not T.same_type(lt, rt):
            self.fail(e.pos, f"'{op}' between {lt} and {rt}: IEC strict typing needs the same "
                      f"type on both sides; convert explicitly (e.g. {_conv_hint(rt, lt)})")
        t = lt
        if t.is_elem and t.kind == "real" and t.bits == 32 and any(
                isinstance(_strip_paren(x), S.RealLit) or (isinstance(_strip_paren(x), S.UnOp)
                                                          and isinstance(_strip_paren(x).operand, S.RealLit))
                for x in (e.left, e.right)):
            self.note(e.pos, "real-literal", f"'{op}' of a REAL with an untyped real literal: "
                      "matiec computes it in double (write REAL#...)")
        if t.is_elem and t.kind == "string" and op in self._CMP:
            self.note(e.pos, "string-compare", "STRING comparison: OpenPLC's fork compares "
                      "the common length only")
        if op in self._CMP or op in ("/", "MOD"):
            self._warn_narrow(e, t)
        if op in self._CMP:
            if t.is_array or t.is_struct or t.is_fb:
                self.fail(e.pos, f"cannot compare values of type {t}")
            if t.is_enum and op not in ("=", "<>"):
                self.fail(e.pos, f"'{op}' on enumerated type {t}: only = and <> are allowed")
            return T.BOOL
        if op in self._LOGIC:
            if not (t.is_elem and t.is_anybit):
                self.fail(e.pos, f"{op} needs BOOL or a bit string type (BYTE/WORD/DWORD/LWORD), "
                          f"not {t}")
            return t
        if t.is_elem and t.kind == "string":
            self.fail(e.pos, f"'{op}' on STRING is not defined: use CONCAT, LEN")
        # arithmetic
        if not t.is_elem:
            self.fail(e.pos, f"'{op}' on {t}")
        if op == "/" and t.is_int and self.const_value(e.right) == 0:
            self.fail(e.right.pos, f"division by constant zero (matiec rejects it)")
        if op == "MOD":
            if not t.is_int:
                self.fail(e.pos, f"MOD needs an integer type, not {t}")
            return t
        if op == "**":
            if t.kind != "real":
                self.fail(e.pos, f"'**' needs REAL or LREAL, not {t}")
            return t
        if t.kind == "time":
            if op in ("+", "-"):
                return t
            self.fail(e.pos, f"TIME {op} TIME is not defined")
        if not t.is_num:
            self.fail(e.pos, f"arithmetic '{op}' on {t} is not allowed (matiec rejects it: "
                      f"{t.name} is a bit string): convert first, e.g. {t.name}_TO_UINT(x) {op} 1")
        return t

    # ---- portability warnings: constructs whose value differs between matiec and IEC
    def _warn_time_scale(self, e, te, ke):
        tv = _time_const(te)
        if tv is not None and tv % 1_000_000_000 == 0 and e.op == "*" and \
                ke.ty is not None and ke.ty.is_elem and ke.ty.is_int:
            return      # whole seconds times an integer: matiec computes it exactly
        kv = self.const_value(ke)
        if tv is not None and kv is not None:
            if (e.op == "*" and _matiec_time_mul(tv, kv) == tv * kv) or \
                    (e.op == "/" and kv != 0 and abs(tv) % 1_000_000_000 < 2**31 and
                     _matiec_time_div(tv, kv) == int(tv / kv)):
                return
        if e.op == "/" and kv is not None and isinstance(kv, int) and 1 <= kv <= 512 and \
                kv & (kv - 1) == 0 and ke.ty is not None and ke.ty.is_elem and ke.ty.is_int:
            # a power of two up to 2**9 divides 10**9: matiec's double arithmetic is exact and
            # truncates toward zero like IEC, for every TIME
            return
        if e.op == "*" and tv is not None and self._mod_bound_exact(tv, ke):
            # T#1ms * (n MOD 1000): the factor is bounded, the product stays inside matiec's
            # 32-bit nanoseconds (the form docs/wiring-openplc.md recommends)
            return
        if e.op == "*":
            self.warn(e.pos, "portability: TIME * number differs between matiec and IEC: matiec "
                      "scales the sub-second part through a 32-bit int of nanoseconds "
                      "(T#1ms * 2148 gives -2.147 s); build it from whole seconds and "
                      "milliseconds: T#1s * (n / 1000) + T#1ms * (n MOD 1000)")
        else:
            self.warn(e.pos, "portability: TIME / number differs between matiec and IEC: "
                      "matiec divides seconds and nanoseconds in double, so the result can be "
                      "some ns off (more for long TIMEs)")

    def _mod_bound_exact(self, tv, ke):
        """ke is (x MOD c) with a constant c, and tv * k is exact in matiec for every
        remainder k (-(c-1) .. c-1)."""
        while isinstance(ke, S.Paren):
            ke = ke.inner
        if not (isinstance(ke, S.BinOp) and ke.op == "MOD"):
            return False
        c = self.const_value(ke.right)
        if not isinstance(c, int) or not 1 <= abs(c) <= 100_000:
            return False
        return all(_matiec_time_mul(tv, k) == tv * k for k in (abs(c) - 1, 1 - abs(c))) and \
            abs(tv) * (abs(c) - 1) < 2**31

    def _warn_narrow(self, e, t):
        if getattr(e, "fn_form", False):
            return
        if not (t.is_elem and t.kind in ("sint", "uint", "bit") and t.bits < 32):
            return
        for x in (e.left, e.right):
            while isinstance(x, S.Paren):
                x = x.inner
            arith = isinstance(x, S.BinOp) and x.op in ("+", "-", "*") or \
                isinstance(x, S.UnOp) and (x.op == "-" or x.op == "NOT" and t.kind != "bool")
            if arith and self.const_value(x) is None:
                self.warn(x.pos, f"portability: the intermediate value of this {t} expression "
                          f"is not truncated to {t} by matiec (C computes it in 32-bit int) "
                          f"but is by IEC: assign it to a variable of type {t} first")
                return

    def _power(self, e, lt, rt):
        """x ** y (EXPT): x REAL or LREAL, y any number; the result has x's type."""
        if lt.is_lit:
            if lt.kind != "real":
                self.fail(e.left.pos, "'**' needs REAL or LREAL on the left: write a REAL "
                          "literal like 2.0")
            if e.left.ty is not None and not e.left.ty.is_lit:
                lt = e.left.ty          # settled by the context already
            else:
                lt = rt if rt.is_elem and rt.kind == "real" else T.ELEMENTARY["LREAL"]
                self.settle(e.left, lt)
        if not (lt.is_elem and lt.kind == "real"):
            self.fail(e.pos, f"'**' needs REAL or LREAL, not {lt}")
        if rt.is_lit:
            self.settle(e.right, lt if rt.kind == "real" else T.DINT)
        elif not (rt.is_elem and rt.is_num):
            self.fail(e.right.pos, f"'**': the exponent must be a number, not {rt}")
        return lt

    def coerce(self, e, from_t, to_t, what, soft=False):
        """Check that a value of from_t can be stored in to_t; settle literals."""
        if self.strict_iec and not soft:
            self._strict_bit_literal(e, to_t, what)
        if from_t.is_lit:
            if to_t.is_lit:
                return
            if from_t.kind == "int":
                if to_t.is_elem and (to_t.is_int or to_t.kind in ("bit", "bool")):
                    v = self.const_value(e)
                    if v is not None and not soft and not _lit_fits(v, to_t):
                        self.fail(e.pos, f"value {v} is out of range of {to_t}")
                    self.settle(e, to_t)
                    return
            elif from_t.kind == "real":
                if to_t.is_elem and to_t.kind == "real":
                    self.settle(e, to_t)
                    return
            if soft:
                return
            if from_t.kind == "int" and to_t.is_elem and to_t.kind == "real":
                self.fail(e.pos, f"{what}: an integer literal cannot be {to_t} (matiec rejects it): "
                          "write a REAL literal like 1.0")
            self.fail(e.pos, f"{what}: {from_t} cannot be {to_t}")
        if soft:
            return
        if T.same_type(from_t, to_t):
            return
        if self._vendor() and from_t.is_array and to_t.is_array and T.same_type(from_t, to_t, False):
            return    # the vendor dialects assign arrays of the same bounds and element type
        if from_t.is_array and to_t.is_array and self.file in self.scl_files:
            self.fail(e.pos, f"{what}: {from_t} cannot be {to_t}: SCL assigns and passes arrays "
                      "only between the same bounds and element type")
        if from_t.is_array and to_t.is_array:
            self.fail(e.pos, f"{what}: arrays can only be assigned or passed between variables of "
                      "the same named array TYPE (matiec rejects anonymous ARRAY[..] types here): "
                      "declare a TYPE and use it on both sides")
        self.fail(e.pos, f"{what}: type {from_t} cannot be assigned to {to_t} without explicit "
                  f"conversion (IEC strict typing): use {_conv_hint(from_t, to_t)}")

    def _strict_bit_literal(self, e, to_t, what):
        """--strict-iec: an untyped decimal integer literal stored in an ANY_BIT variable (BYTE,
        WORD, DWORD, LWORD). matiec, CODESYS and TwinCAT accept it; a strict IEC 61131-3
        edition-2 checker does not (a decimal literal is ANY_INT there). Typed (WORD#0) and
        based (16#0) literals are bit strings."""
        if (isinstance(e, S.IntLit) and not e.based and to_t.is_elem and to_t.kind == "bit"):
            self.warn(e.pos, f"strict IEC: {what}: untyped integer literal {e.text} stored in "
                             f"{to_t} (a strict edition-2 checker rejects it): write "
                             f"{to_t}#{e.text} or a based literal like 16#{e.value:X}")

    def need_settled(self, e, t):
        if e.ty is None or e.ty.is_lit:
            if e.ty is not None and e.ty.kind == "int" and t.is_elem and t.kind == "real":
                self.fail(e.pos, f"an integer literal cannot be used as {t} (matiec rejects it): "
                          "write a REAL literal like 1.0")
            self.fail(e.pos, f"{e.ty or 'this value'} cannot be used as {t}")

    def range_check(self, e, t):
        if t.is_elem and (t.is_int or t.kind == "bit"):
            v = self.const_value(e)
            if v is not None and not _lit_fits(v, t):
                self.fail(e.pos, f"value {v} is out of range of {t}")

    def settle(self, e, t):
        """Give untyped literal expression e the concrete type t (recursively)."""
        if e.ty is not None and not e.ty.is_lit:
            return
        e.ty = t
        if isinstance(e, S.Paren):
            self.settle(e.inner, t)
        elif isinstance(e, S.UnOp):
            if e.op == "-" and not (t.is_elem and t.kind in ("sint", "real", "time")):
                self.fail(e.pos, f"unary minus on a value of type {t}")
            self.settle(e.operand, t)
        elif isinstance(e, S.BinOp):
            if e.op in self._ARITH and not (t.is_elem and t.is_num):
                self.fail(e.pos, f"arithmetic '{e.op}' on literals used as {t} is not allowed: "
                          "compute it in an integer type")
            if e.op == "MOD" and not t.is_int:
                self.fail(e.pos, f"MOD needs an integer type, not {t}")
            if e.op in self._LOGIC and not (t.is_elem and t.is_anybit):
                self.fail(e.pos, f"{e.op} needs BOOL or a bit string type, not {t}")
            self.settle(e.left, t)
            self.settle(e.right, t)

    def const_value(self, e):
        """Integer value of a constant integer expression, or None."""
        if isinstance(e, S.IntLit):
            return e.value
        if isinstance(e, S.TypedLit) and e.kind == "int":
            return e.value
        if isinstance(e, S.Paren):
            return self.const_value(e.inner)
        if isinstance(e, S.UnOp) and e.op == "-":
            v = self.const_value(e.operand)
            return -v if v is not None else None
        if isinstance(e, S.UnOp) and e.op == "+":
            return self.const_value(e.operand)
        if isinstance(e, S.BinOp) and e.op in ("+", "-", "*"):
            a, b = self.const_value(e.left), self.const_value(e.right)
            if a is None or b is None:
                return None
            return a + b if e.op == "+" else a - b if e.op == "-" else a * b
        return None

    # ---- calls
    def call(self, c, statement, expected=None):
        name = c.name
        v = self.scope.get(name)
        if v is not None:
            if not v.type.is_fb:
                self.fail(c.pos, f"'{name}' is a variable of type {v.type}, not a function block "
                          "instance")
            if not statement:
                self.fail(c.pos, f"function block instance '{name}' cannot be called in an "
                          f"expression: call it as a statement and read {name}.Q")
            c.kind = "fb"
            c.var = v
            self.bind_args(c, v.type.pou, fb=True)
            for pn, pv in v.type.pou.vars.items():
                if pv.kind == "VAR_IN_OUT" and pv.type.is_fb and pn not in c.bound:
                    # (vendor dialects only: an FB in-out is a reference, as CODESYS's rClient)
                    self.err(c.pos, f"{pn}, a VAR_IN_OUT of {v.type.pou.name}, must be given in "
                             "every call (the IDEs require it; unbound it refers to nothing)")
            self._warn_std_fb(c, v.type.pou)
            return None
        if name in T.STD_FBS or (name in self.p.pous and self.p.pous[name].kind == "function_block"):
            self.fail(c.pos, f"'{name}' is a function block type: declare an instance and call that")
        if name in self.p.pous:
            pou = self.p.pous[name]
            if pou.kind != "function":
                self.fail(c.pos, f"'{name}' is a {pou.kind.replace('_', ' ').upper()}, which cannot be called")
            if self.cur is not None and pou is self.cur:
                self.fail(c.pos, "recursion is not allowed in IEC 61131-3")
            c.kind = "func"
            c.pou = pou
            if not c.args:
                self.fail(c.pos, f"calling a FUNCTION without arguments ({name}()) is not portable "
                          "(matiec rejects it): give it a VAR_INPUT")
            self.bind_args(c, pou, fb=False)
            if statement:
                return None
            return pou.rtype
        conv = _conversion(name)
        if conv is not None:
            return self.conversion(c, conv)
        if name in T.STD_FUNCS:
            return self.std_func(c, expected)
        if name in _VENDOR_FUNCS and self._vendor():
            return self.vendor_func(c)
        if name.startswith("TO_") and self._vendor() and name[3:] in T.ELEMENTARY \
                and T.ELEMENTARY[name[3:]].kind in ("sint", "uint", "bit") and len(c.args) == 1 \
                and isinstance(c.args[0], S.ArgPos):
            # TO_WORD(eErrorID): the number of an enumerated value (CODESYS)
            at = self.expr(c.args[0].value, None)
            if not at.is_enum:
                self.fail(c.pos, f"{name} of a {at} is not supported: use a typed conversion "
                          f"({at}_TO_{name[3:]})")
            c.kind = "vendor"
            c.argv = [c.args[0].value]
            return T.ELEMENTARY[name[3:]]
        if name.startswith("TO_"):
            self.fail(c.pos, f"generic conversion {name} is not portable (matiec rejects it): "
                      "use a typed conversion like INT_TO_UINT")
        self.fail(c.pos, f"unknown function '{name}'")

    def vendor_func(self, c):
        """ADR(x), SIZEOF(x) and MEMCPY(destAddr, srcAddr, n) of the TwinCAT / CODESYS
        dialects (Tc2_System MEMCPY; CODESYS SysMemCpy(pDest, pSrc, udiCount))."""
        n = c.name
        names = _VENDOR_FUNCS[n]
        args = [None] * len(names)
        for i, a in enumerate(c.args):
            if isinstance(a, S.ArgPos) and all(x is None for x in args[i:]):
                if i >= len(names):
                    self.fail(a.pos, f"{n} takes {len(names)} argument(s)")
                args[i] = a.value
            elif isinstance(a, S.ArgIn) and a.name in names:
                args[names.index(a.name)] = a.value
            else:
                self.fail(a.pos, f"{n}: arguments are {', '.join(names)}")
        if any(x is None for x in args):
            self.fail(c.pos, f"{n} needs {', '.join(names)}")
        c.kind = "vendor"
        c.argv = args
        if n in ("ADR", "SIZEOF"):
            x = args[0]
            if not _is_variable(x) and not isinstance(x, S.Deref):
                self.fail(x.pos, f"{n} takes a variable")
            t = self.expr(x, None)
            if t.is_fb:
                self.fail(x.pos, f"{n} of a function block instance is not supported")
            return T.PointerT(t) if n == "ADR" else T.ELEMENTARY["UDINT"]
        for x in args[:2]:
            t = self.expr(x, None)
            if not isinstance(t, T.PointerT):
                self.fail(x.pos, f"{n}: an address (ADR(...) or a POINTER), not {t}")
        t = self.expr(args[2], T.ELEMENTARY["UDINT"])
        self.coerce(args[2], t, T.ELEMENTARY["UDINT"], f"{n}'s byte count")
        return T.ELEMENTARY["UDINT"]

    def _warn_std_fb(self, c, pou):
        std = pou.std.name if pou.std is not None else None
        if std == "F_TRIG":
            clk = c.bound.get("CLK")
            if not (isinstance(clk, S.BoolLit) and clk.value):
                self.warn(c.pos, "portability: F_TRIG differs between matiec and the OpenPLC "
                          "fork / IEC mode on the first call: matiec gives Q = TRUE when CLK is "
                          "FALSE on the first call; ignore Q on the first scan")
        elif std in ("TON", "TOF", "TP"):
            pt = c.bound.get("PT")
            k = _strip_paren(pt).ns if isinstance(_strip_paren(pt), S.TimeLit) else None
            if k is not None and k <= 0:
                self.warn(pt.pos, f"portability: {std} with PT = T#0s differs between matiec and "
                          "IEC: matiec's Q changes one call late (it compares from the call after "
                          "the edge)")
            elif k is None and not _is_false(c.bound.get("IN")):
                self.note(c.pos, "timer-pt", f"{std} with a PT that is not a constant: at "
                          "T#0s matiec's Q changes one call late")
        elif std in ("CTU", "CTD", "CTUD"):
            self.warn(c.pos, f"portability: {std} differs between matiec and IEC at its limits: "
                      "matiec stops counting up at PV and down at 0, IEC at the limits of INT")

    def bind_args(self, c, pou, fb):
        params = [v for v in pou.vars.values() if v.kind in ("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT")]
        inputs = [v for v in params if v.kind in ("VAR_INPUT", "VAR_IN_OUT")]
        bound = {}
        outs = []
        positional = [a for a in c.args if isinstance(a, S.ArgPos)]
        named = [a for a in c.args if not isinstance(a, S.ArgPos)]
        if positional and named:
            self.fail(c.pos, "mixing positional and named (:=) arguments is not allowed")
        if positional:
            if len(positional) > len(inputs):
                self.fail(c.pos, f"{pou.name} takes {len(inputs)} inputs, got {len(positional)}")
            for a, p in zip(positional, inputs):
                bound[p.name] = a.value
        c.en = c.eno = None
        for a in named:
            if a.name in ("EN", "ENO") and isinstance(a, S.ArgIn if a.name == "EN" else S.ArgOut):
                if not fb and pou.rtype is not None and not pou.rtype.is_elem and not pou.rtype.is_enum:
                    self.err(a.pos, f"EN/ENO on a call of {pou.name}, which returns {pou.rtype}, "
                             "is not supported by stc: test the condition around the call")
                    continue
                # EN := cond runs the body only when cond is TRUE; ENO => v tells whether it ran
                self.note(a.pos, "en-eno", "EN/ENO on a call: matiec keeps EN from the last "
                          "call that gave it")
                if a.name == "EN":
                    self.cond(a.value, "EN")
                    c.en = a.value
                else:
                    if a.negate:
                        self.err(a.pos, "NOT x => y is not supported: negate afterwards")
                        continue
                    tt = self.lvalue(a.target, "assign to")
                    if not T.same_type(tt, T.BOOL):
                        self.err(a.target.pos, f"ENO is BOOL but '=>' target is {tt}")
                    c.eno = a.target
                continue
            p = pou.vars.get(a.name)
            if p is None or p.kind not in ("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT"):
                self.err(a.pos, f"{pou.name} has no parameter '{a.name}'")
                continue
            if isinstance(a, S.ArgIn):
                if p.kind == "VAR_OUTPUT":
                    self.err(a.pos, f"'{a.name}' is an output of {pou.name}: use {a.name} => variable")
                    continue
                if a.name in bound:
                    self.err(a.pos, f"parameter '{a.name}' given twice")
                bound[a.name] = a.value
            else:
                if p.kind != "VAR_OUTPUT":
                    self.err(a.pos, f"'{a.name}' is not an output of {pou.name}: use {a.name} := value")
                    continue
                if a.negate:
                    self.err(a.pos, "NOT x => y is not supported: negate afterwards")
                    continue
                tt = self.lvalue(a.target, "assign to")
                if not T.same_type(p.type, tt):
                    self.err(a.target.pos, f"output {a.name} is {p.type} but '=> ' target is {tt}")
                outs.append((p, a.target))
        c.bound = {}
        for p in inputs:
            e = bound.get(p.name)
            if e is None:
                if p.kind == "VAR_IN_OUT":
                    if fb:
                        # matiec accepts it: the instance keeps the variable of its last call
                        self.warn(c.pos, f"portability: VAR_IN_OUT '{p.name}' of {pou.name} is "
                                  "not passed: the instance uses the variable of its previous "
                                  "call (none on the first call: the program crashes)")
                    else:
                        self.err(c.pos, f"VAR_IN_OUT '{p.name}' of {pou.name} must be passed")
                continue
            try:
                if p.kind == "VAR_IN_OUT" and p.type.is_fb and isinstance(e, S.Name):
                    # an FB instance bound to an FB in-out (vendor dialects: CODESYS's rClient)
                    v = self.lookup(e)
                    e.var, e.ty, t = v, v.type, v.type
                elif p.kind == "VAR_IN_OUT":
                    t = self.lvalue(e, "pass as VAR_IN_OUT")
                    if not _is_variable(e):
                        self.fail(e.pos, f"VAR_IN_OUT '{p.name}' needs a variable")
                    if not T.same_type(t, p.type) and not (
                            self._vendor() and t.is_array and T.same_type(t, p.type, False)):
                        self.fail(e.pos, f"VAR_IN_OUT '{p.name}' is {p.type}, got {t}")
                else:
                    t = self.expr(e, p.type)
                    self.coerce(e, t, p.type, f"input {p.name} of {pou.name}")
                c.bound[p.name] = e
            except CompileError:
                pass
        c.outs = outs

    def str_func(self, c, n, expected):
        """LEFT RIGHT MID FIND INSERT DELETE REPLACE: positional, or formal with the standard's
        parameter names (IN, IN1, IN2, L, P) in any order."""
        names = T.STR_FUNCS[n]
        if len(c.args) != len(names):
            self.fail(c.pos, f"{n} takes {len(names)} arguments ({', '.join(names)}), got {len(c.args)}")
        if all(isinstance(a, S.ArgIn) for a in c.args):
            given = {a.name: a.value for a in c.args}
            if set(given) != set(names):
                self.fail(c.pos, f"{n} takes the inputs {', '.join(names)}")
            args = [given[k] for k in names]
        elif any(isinstance(a, S.ArgIn) for a in c.args):
            self.fail(c.pos, "mixing positional and named (:=) arguments is not allowed")
        else:
            args = [a.value for a in c.args]
        for k, a in zip(names, args):
            if k.startswith("IN"):
                t = self.expr(a, T.STRING)
                if not T.same_type(t, T.STRING):
                    self.fail(a.pos, f"{n}: {k} is a STRING, not {t}")
            else:
                t = self.expr(a, None)
                if t.is_lit and t.kind != "real":
                    self.settle(a, T.INT)
                elif not (t.is_elem and t.is_int):
                    self.fail(a.pos, f"{n}: {k} is an integer, not {t}")
        c.argv = args
        return _int_result(expected) if n == "FIND" else T.STRING

    def conversion(self, c, conv):
        src, dst = conv
        args = c.args
        if len(args) != 1 or not isinstance(args[0], S.ArgPos):
            self.fail(c.pos, f"{c.name} takes one argument")
        a = args[0].value
        st = T.ELEMENTARY[src]
        t = self.expr(a, st)
        self.coerce(a, t, st, f"argument of {c.name}")
        c.kind = "conv"
        c.conv = (T.ELEMENTARY[src], T.ELEMENTARY[dst])
        return T.ELEMENTARY[dst]

    def std_func(self, c, expected):
        n = c.name
        c.kind = "std"
        args = []
        for a in c.args:
            if not isinstance(a, S.ArgPos):
                if isinstance(a, S.ArgIn):
                    args.append(a.value)
                    continue
                self.fail(a.pos, f"{n} has no outputs")
            args.append(a.value)
        c.argv = args

        def need(k):
            if len(args) != k:
                self.fail(c.pos, f"{n} takes {k} arguments, got {len(args)}")

        def same(es, hint):
            ts = [self.expr(x, hint) for x in es]
            conc = [t for t in ts if not t.is_lit]
            if not conc:
                t0 = hint if hint is not None and hint.is_elem else (
                    T.ELEMENTARY["LREAL"] if any(t.kind == "real" for t in ts) else T.DINT)
            else:
                t0 = conc[0]
            for x, t in zip(es, ts):
                if t.is_lit:
                    self.coerce(x, t, t0, f"argument of {n}")
                elif not T.same_type(t, t0):
                    self.fail(x.pos, f"{n}: arguments must all have the same type ({t0}), got {t}; "
                              "convert explicitly")
            return t0

        if n in ("SHL", "SHR", "ROL", "ROR"):
            need(2)
            t = self.expr(args[0], expected)
            if t.is_lit:
                self.fail(args[0].pos, f"{n} of an untyped literal: write a typed literal like WORD#16#FF")
            if not (t.is_elem and t.is_anybit):
                self.fail(args[0].pos, f"{n} needs BOOL, BYTE, WORD, DWORD or LWORD, not {t}")
            nt = self.expr(args[1], None)
            if nt.is_lit:
                self.settle(args[1], T.DINT)
            elif not (nt.is_elem and nt.is_int):
                self.fail(args[1].pos, f"{n}: shift count must be an integer, not {nt}")
            if n in ("SHL", "SHR") and t.bits > 1:
                k = self.const_value(args[1])
                cw = 64 if t.bits == 64 else 32
                if k is None:
                    self.warn(args[1].pos, f"portability: {n} by a variable count differs between "
                              f"matiec and IEC when the count is >= {cw} (matiec shifts in C: "
                              f"x86 takes the count modulo {cw}); limit the count first")
                elif not 0 <= k < cw:
                    self.warn(args[1].pos, f"portability: {n} of {t} by {k} differs between "
                              "matiec and IEC (IEC shifts everything out)")
            return t
        if n in ("ABS",):
            need(1)
            t = same(args, expected)
            if not (t.is_elem and t.is_num):
                self.fail(c.pos, f"ABS needs a numeric type, not {t}")
            return t
        if n == "LEN":
            need(1)
            t = self.expr(args[0], T.STRING)
            if not T.same_type(t, T.STRING):
                self.fail(args[0].pos, f"LEN needs a STRING, not {t}")
            return _int_result(expected)
        if n in T.STR_FUNCS:
            self.note(c.pos, "string-function", f"{n}: matiec's library has its own results "
                      "at the edges (FIND, REPLACE, positions 0)")
            return self.str_func(c, n, expected)
        if n == "CONCAT":
            if len(args) < 2:
                self.fail(c.pos, "CONCAT takes at least 2 arguments")
            for a in args:
                t = self.expr(a, T.STRING)
                if not T.same_type(t, T.STRING):
                    self.fail(a.pos, f"CONCAT needs STRINGs, not {t}")
            return T.STRING
        if n in ("SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN"):
            need(1)
            t = same(args, expected)
            if not (t.is_elem and t.kind == "real"):
                if t.is_elem and t.is_int:
                    self.fail(args[0].pos, f"{n} needs REAL or LREAL, not {t} (matiec rejects "
                              f"it): convert first, e.g. {t.name}_TO_REAL(x)")
                self.fail(args[0].pos, f"{n} needs REAL or LREAL, not {t}")
            c.kind = "math"
            return t
        if n == "TRUNC":
            need(1)
            t = self.expr(args[0], None)
            if t.is_lit and t.kind == "real":
                self.settle(args[0], T.ELEMENTARY["LREAL"])
                t = args[0].ty
            if not (t.is_elem and t.kind == "real"):
                self.fail(args[0].pos, f"TRUNC needs REAL or LREAL, not {t}")
            if expected is None or not (expected.is_elem and expected.is_int):
                self.fail(c.pos, "TRUNC: the result type must come from the context (assign it to "
                          "an integer variable) or use REAL_TO_DINT")
            c.kind = "trunc"
            return expected
        if n in ("MOVE",):
            need(1)
            t = same(args, expected)
            if t.is_array:
                self.fail(c.pos, "MOVE of an ARRAY is not supported: assign the array variable")
            return t
        if n in ("MIN", "MAX"):
            if len(args) < 2:
                self.fail(c.pos, f"{n} takes at least 2 arguments")
            t = same(args, expected)
            if not t.is_elem or t.kind == "string":
                self.fail(c.pos, f"{n} needs a number, bit string or TIME, not {t}")
            return t
        if n == "LIMIT":
            need(3)
            t = same(args, expected)
            if not t.is_elem or t.kind == "string":
                self.fail(c.pos, f"LIMIT needs a number, bit string or TIME, not {t}")
            return t
        if n == "SEL":
            need(3)
            self.cond(args[0], "SEL selector")
            t = same(args[1:], expected)
            if t.is_fb or t.is_array:
                self.fail(c.pos, f"SEL of {t} is not supported")
            return t
        if n == "MUX":
            if len(args) < 2:
                self.fail(c.pos, "MUX takes a selector and at least one input")
            kt = self.expr(args[0], None)
            if kt.is_lit:
                self.settle(args[0], T.DINT)
            elif not (kt.is_elem and kt.is_int):
                self.fail(args[0].pos, f"MUX selector must be an integer, not {kt}")
            t = same(args[1:], expected)
            if t.is_fb or t.is_array:
                self.fail(c.pos, f"MUX of {t} is not supported")
            k = self.const_value(args[0])
            if k is not None and not 0 <= k < len(args) - 1:
                self.warn(args[0].pos, f"portability: MUX selector {k} is out of range 0.."
                          f"{len(args) - 2}: matiec gives 0, IEC leaves it undefined (stc "
                          "--semantics=iec gives the last input)")
            return t
        if n in ("ADD", "SUB", "MUL", "DIV"):
            need(2)
            op = {"ADD": "+", "SUB": "-", "MUL": "*", "DIV": "/"}[n]
            b = S.BinOp(c.pos, op, args[0], args[1])
            b.fn_form = True      # matiec: a typed function, its arguments are truncated
            t = self.binop(b, expected)
            b.ty = t
            c.kind = "binop"
            c.binop = b
            return t
        if n == "EXPT":
            need(2)
            t = same(args[:1], expected)
            if not (t.is_elem and t.kind == "real"):
                self.fail(c.pos, f"EXPT needs REAL or LREAL, not {t}")
            et = self.expr(args[1], None)
            if et.is_lit:
                self.settle(args[1], t if et.kind == "real" else T.DINT)
            elif not (et.is_elem and et.is_num):
                self.fail(args[1].pos, f"EXPT: the exponent must be a number, not {et}")
            c.kind = "math"
            return t
        self.fail(c.pos, f"standard function {n} is not supported by stc")


# the vendor dialects' address functions: argument names in order (Tc2_System / CODESYS)
_VENDOR_FUNCS = {"ADR": ("IN",), "SIZEOF": ("IN",), "MEMCPY": ("DESTADDR", "SRCADDR", "N"),
                 "SYSMEMCPY": ("PDEST", "PSRC", "UDICOUNT")}


def _is_false(e):
    e = _strip_paren(e) if e is not None else None
    return isinstance(e, S.BoolLit) and not e.value


def _strip_paren(e):
    while isinstance(e, S.Paren):
        e = e.inner
    return e


def _int_result(expected):
    """Result type of LEN and FIND (ANY_INT in matiec): the integer type the context wants,
    INT otherwise."""
    if expected is not None and expected.is_elem and expected.is_int and not expected.is_lit:
        return expected
    return T.INT


_KW = []

# standard function names matiec accepts as STRUCT member names (a member is always written
# after a '.', so it cannot be mistaken for the function)
_MEMBER_OK = {"LEN", "LEFT", "RIGHT", "MID", "FIND"}


_STR_ESC = {"$": "$", "'": "'", '"': '"', "L": "\n", "N": "\n", "P": "\f", "R": "\r",
            "T": "\t"}


def _string_value(body):
    """Characters of a STRING literal body ($ escapes decoded), None when malformed."""
    out = []
    i = 0
    while i < len(body):
        ch = body[i]
        if ch != "$":
            out.append(ch)
            i += 1
            continue
        nxt = body[i + 1:i + 2].upper()
        if nxt in _STR_ESC:
            out.append(_STR_ESC[nxt])
            i += 2
        elif re.fullmatch(r"[0-9A-Fa-f]{2}", body[i + 1:i + 3]):
            out.append(chr(int(body[i + 1:i + 3], 16)))
            i += 3
        else:
            return None
    return "".join(out)


def _time_const(e):
    while isinstance(e, S.Paren):
        e = e.inner
    if isinstance(e, S.TimeLit):
        return e.ns
    return None


def _c_div(a, b):
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q


def _c_i32(d):
    return int(d) if -2**31 <= d < 2**31 else -2**31


def _c_i64(d):
    return int(d) if -9.2e18 <= d < 9.2e18 else -2**63


def _matiec_time_mul(ns, k):
    """matiec's TIME * k in nanoseconds (see stc_mt_mul in stc_rt.h)."""
    sec, nsec = _c_div(ns, 10**9), ns - _c_div(ns, 10**9) * 10**9
    s_f = float(sec) * k
    s = _c_i64(s_f)
    n = _c_i32(float(nsec) * k)
    q = _c_div(n, 10**9)
    return (s + q) * 10**9 + _c_i64(float(n - q * 10**9) + (s_f - s) * 1e9)


def _matiec_time_div(ns, k):
    sec, nsec = _c_div(ns, 10**9), ns - _c_div(ns, 10**9) * 10**9
    s_f = float(sec) / k
    s = _c_i64(s_f)
    return s * 10**9 + _c_i64(float(nsec) / k + (s_f - s) * 1e9)


def _keywords():
    if not _KW:
        from . import parser
        parser._get_parser()
        _KW.append(parser.KEYWORDS)
    return _KW[0]


def _is_variable(e):
    return isinstance(e, (S.Name, S.Field, S.Index))


def _conversion(name):
    if "_TO_" not in name:
        return None
    a, _, b = name.partition("_TO_")
    if a in T.CONVERTIBLE and b in T.CONVERTIBLE and a != b:
        return (a, b)
    if "STRING" in (a, b) and a != b and (a in T.CONVERTIBLE or b in T.CONVERTIBLE) \
            and "TIME" not in (a, b):
        return (a, b)       # <elementary>_TO_STRING, STRING_TO_<elementary> (not TIME)
    return None


def _conv_hint(f, t):
    if f.is_elem and t.is_elem and f.name in T.CONVERTIBLE and t.name in T.CONVERTIBLE:
        return f"{f.name}_TO_{t.name}(...)"
    return "an explicit conversion"


def _addr_text(v):
    area, size, parts = v.location
    return "%" + area + size + ".".join(str(p) for p in parts)
