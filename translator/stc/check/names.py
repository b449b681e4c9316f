"""Names and types: identifiers, named and anonymous types, initial values, constants."""
from .. import syntax as S
from .. import types as T
from ..diag import CompileError
from .project import Pou, Var
from .helpers import _C_MACROS, _MEMBER_OK, _conversion, _keywords


class TypeChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

    def _declare_name(self, name, pos, kind):
        self._check_ident(name, pos)
        if name in self.p.types or name in self.p.pous:
            self.err(pos, "S0101", f"'{name}' is declared twice")
            return False
        if name in T.STD_FBS or name in T.ELEMENTARY or _conversion(name):
            self.err(pos, "S0102", f"'{name}' is a standard library name and cannot be redeclared")
            return False
        return True

    def _check_ident(self, name, pos, member=False):
        if member and name in _MEMBER_OK:
            return
        if "__" in name:
            self.err(pos, "S0103", f"identifier '{name}' contains '__', which matiec rejects: use a single '_'")
        elif name.endswith("_"):
            self.err(pos, "S0104", f"identifier '{name}' ends with '_', which matiec rejects")
        elif _C_MACROS.match(name):
            self.err(pos, "S0105", f"identifier '{name}' is a C macro name in the generated code: rename it")
        elif name in T.RESERVED or name in _keywords() or _conversion(name):
            self.err(pos, "S0106", f"'{name}' is a reserved or standard library name in matiec and cannot "
                     "be used as an identifier")

    # ---- types
    def _resolve_named(self, name):
        t = self.p.types.get(name)
        if t is not None:
            return t
        fname, td = self.p.type_files[name]
        if name in self._resolving:
            self.err(td.pos, "S0107", f"type '{name}' is defined in terms of itself", fname)
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
                if vval is not None and not self.dialect.enum_explicit_values:
                    self.err(vpos, "S0108", "enumerated values with explicit values (A := 0) are not "
                             "portable (matiec rejects them): declare (A, B, ...) and convert "
                             "with CASE")
                self._check_ident(vname, vpos)
                if vname in vals:
                    self.err(vpos, "S0109", f"enumerated value '{vname}' is declared twice")
                # the vendor dialects: A := n, and the next one without a value is n + 1
                code = vval if vval is not None else (codes[-1] + 1 if codes else 0)
                explicit = explicit or vval is not None
                if code in codes:
                    self.err(vpos, "S0110", f"enumerated value '{vname}' = {code} repeats another's value")
                vals.append(vname)
                codes.append(code)
            t = T.EnumT(td.name, vals, codes=codes if explicit else None)
            if spec.default is not None:
                if spec.default not in vals:
                    self.err(spec.pos, "S0111", f"'{spec.default}' is not a value of {td.name}")
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
                        self.err(mpos, "S0112", f"member '{mname}' is declared twice")
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
            self.fail(td.pos, "S0113", "a TYPE cannot be an alias of a function block")
        else:
            t = base   # alias of a struct or enum: same type
        if td.init is not None:
            self.check_init(td.init, t)
            if t is base:
                self.err(td.pos, "S0114", "an initial value on an alias of a STRUCT or enumerated type is "
                         "not supported: put it on the variables")
            else:
                t.default = td.init
        return t

    def resolve_type(self, spec, member=False, in_array=False):
        if isinstance(spec, S.PointerRef):
            if spec.word != "POINTER" or not self.dialect.pointers:
                self.fail(spec.pos, "S0115", f"{spec.word} TO is not portable (matiec rejects pointers and "
                          "references); pointers are read in the TwinCAT / CODESYS dialects only "
                          "(--dialect=twincat|codesys)" if spec.word == "POINTER" else
                          f"unexpected '{spec.word} TO'")
            target = self.resolve_type(spec.target, member=True)
            if target.is_array and not target.name or target.is_fb:
                self.fail(spec.pos, "S0116", "POINTER TO an anonymous ARRAY or a function block is not "
                          "supported: declare an array TYPE")
            return T.PointerT(target)
        if isinstance(spec, S.NamedType):
            n = spec.name
            if n == "PVOID" and self.dialect.pointers:
                return T.PointerT(T.ELEMENTARY["BYTE"])
            if n in T.ELEMENTARY:
                return T.ELEMENTARY[n]
            if n in self.p.types:
                return self._resolve_named(n)
            if n in T.STD_FBS:
                if member:
                    self.fail(spec.pos, "S0117", f"a function block ({n}) cannot be a STRUCT member or "
                              "array element (matiec rejects it): declare the instances as "
                              "separate variables")
                return self._std_fb_type(n)
            if n in self.p.pous:
                pou = self.p.pous[n]
                if pou.kind != "function_block":
                    self.fail(spec.pos, "S0118", f"'{n}' is a {pou.kind.replace('_', ' ')}, not a type")
                if member:
                    self.fail(spec.pos, "S0117", f"a function block ({n}) cannot be a STRUCT member or "
                              "array element (matiec rejects it): declare the instances as "
                              "separate variables")
                return T.FBT(n, pou)
            if n in T.UNSUPPORTED_TYPES:
                self.fail(spec.pos, "S0119", f"type {n} is not supported by stc")
            self.fail(spec.pos, "S0120", f"unknown type '{n}'")
        if isinstance(spec, S.ArraySpec):
            dims = []
            for lo, hi in spec.dims:
                if lo is None or hi is None:
                    self.fail(spec.pos, "S0121", "invalid integer in array bounds")
                if isinstance(lo, S.ConstBound) or isinstance(hi, S.ConstBound):
                    b = lo if isinstance(lo, S.ConstBound) else hi
                    self.fail(b.pos, "S0122", "array bounds from a named constant are not portable "
                              "(matiec rejects them): write the number")
                if hi < lo:
                    self.fail(spec.pos, "S0123", f"array range {lo}..{hi} is empty")
                dims.append((lo, hi))
            if isinstance(spec.elem, S.ArraySpec):
                self.fail(spec.elem.pos, "S0124", "ARRAY OF ARRAY is not portable (matiec rejects it): "
                          "use a multi-dimensional array ARRAY[a..b, c..d] OF ...")
            elem = self.resolve_type(spec.elem, member=True, in_array=True)
            if elem.is_array:
                self.fail(spec.elem.pos, "S0125", "ARRAY OF an array type is not portable (matiec rejects "
                          "it): use a multi-dimensional array ARRAY[a..b, c..d] OF ...")
            n = 1
            for lo, hi in dims:
                n *= hi - lo + 1
            if n > 1 << 24:
                self.fail(spec.pos, "S0126", "array too large")
            return T.ArrayT(elem, dims)
        if isinstance(spec, S.SubrangeRef):
            self.fail(spec.pos, "S0127", f"subrange types like {spec.base}(0..100) are not portable "
                      f"(matiec rejects them): use plain {spec.base} and LIMIT()")
        if isinstance(spec, S.StringRef):
            if self.dialect.string_length_decl and spec.base == "STRING" and 0 < int(spec.size) <= T.STR_MAX:
                return T.STRING       # STRING(15) of the vendor blocks: stc's STRING holds it
            self.fail(spec.pos, "S0128", f"{spec.base}[{spec.size}] is not portable (matiec drops or "
                      "crashes on it): use an ARRAY OF BYTE")
        if isinstance(spec, S.StructSpec):
            self.fail(spec.pos, "S0129", "an inline STRUCT in a variable declaration is not supported: "
                      "declare it in a TYPE")
        if isinstance(spec, S.EnumSpec):
            self.fail(spec.pos, "S0130", "an inline enumeration in a variable declaration is not "
                      "supported: declare it in a TYPE")
        self.fail(getattr(spec, "pos", (0, 0)), "S0131", "unsupported type")

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
                    self.fail(init.pos, "S0132", f"an array initialiser [...] needs an ARRAY, not {ty}")
                n = 0
                for count, val in init.items:
                    if count is not None and count <= 0:
                        self.err(init.pos, "S0133", "repetition count must be positive")
                        continue
                    n += count if count is not None else 1
                    if val is not None:
                        self.check_init(val, ty.elem)
                if n > ty.count():
                    self.err(init.pos, "S0134", f"{n} initial values for an array of {ty.count()} elements")
            elif isinstance(init, S.StructInit):
                if not ty.is_struct:
                    self.fail(init.pos, "S0135", f"a structure initialiser (a := ...) needs a STRUCT, not {ty}")
                for name, val, pos in init.items:
                    if name not in ty.fields:
                        self.err(pos, "S0136", f"{ty.name} has no member '{name}'")
                        continue
                    self.check_init(val, ty.fields[name][0])
            else:
                if ty.is_array or ty.is_struct or ty.is_fb:
                    self.fail(init.pos, "S0137", f"initial value of {ty} must be a "
                              + ("[...] list" if ty.is_array else "(member := ...) list"
                                 if ty.is_struct else "nothing"))
                self.scope = {}
                self.cur = None
                t = self.expr(init, ty)
                self.coerce(init, t, ty, "initial value")
                if not self.is_constant(init):
                    self.err(init.pos, "S0138", "initial values must be constant expressions")
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
