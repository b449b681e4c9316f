"""Lookup, lvalues and expressions: literals, unary and binary operators, TIME scaling."""
import re

from .. import matiec_time
from .. import syntax as S
from .. import types as T
from .project import Var
from .helpers import _conv_hint, _lit_fits, _string_value, _strip_paren, _time_const


class ExpressionChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

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
            self.fail(name_node.pos, "S0401", f"{n} in a PROGRAM body is not portable (matiec rejects it)")
        self.fail(name_node.pos, "S0402", f"unknown variable '{n}'")

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
                self.err(e.pos, "S0403", f"cannot {what} CONSTANT '{v.name}'")
            if v.kind == "VAR_INPUT" and self.cur is not None and self.cur.kind == "function":
                pass
            if v.type.is_fb:
                self.err(e.pos, "S0404", f"cannot assign to function block instance '{v.name}'")
            return v.type
        if isinstance(e, S.Field):
            bt = self.expr(e.base, None, lvalue=True)
            if bt.is_fb:
                ft = self.fb_member(e, bt)
                fv = bt.pou.vars.get(e.name)
                if fv is None:
                    self.fail(e.pos, "S0405", f"{e.name} of a function block instance is set by its call "
                              f"(EN := ... in the call), not by an assignment")
                if fv.kind == "VAR_OUTPUT":
                    self.err(e.pos, "S0406", f"writing output {e.name} of function block instance from "
                             "outside is not portable (matiec rejects it)")
                elif fv.kind not in ("VAR_INPUT",):
                    self.err(e.pos, "S0407", f"'{e.name}' is not an input of {bt.name}")
                self._check_base_assignable(e.base)
                return ft
            self._check_base_assignable(e.base)
            return self.expr(e, None)
        if isinstance(e, S.Index):
            self._check_base_assignable(e.base)
            return self.expr(e, None)
        if isinstance(e, (S.BitAccess, S.Deref)):
            return self.expr(e, None)
        self.fail(e.pos, "S0408", "the left side of ':=' must be a variable")

    def _check_base_assignable(self, e):
        while isinstance(e, (S.Field, S.Index)):
            e = e.base
        if isinstance(e, S.Name):
            v = getattr(e, "var", None) or self.scope.get(e.name)
            if v is not None and v.constant:
                self.err(e.pos, "S0409", f"cannot assign to CONSTANT '{v.name}'")

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
                self.fail(e.pos, "S0410", f"'{e.name}' of {bt.name} is not an input or output: internal "
                          "variables are not accessible from outside")
            self.fail(e.pos, "S0411", f"{bt.name} has no input or output '{e.name}'")
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
                self.fail(e.pos, "S0412", f"invalid integer literal {e.text}")
            return T.LIT_INT
        if isinstance(e, S.RealLit):
            return T.LIT_REAL
        if isinstance(e, S.BoolLit):
            return T.BOOL
        if isinstance(e, S.TimeLit):
            if e.ns is None:
                self.fail(e.pos, "S0413", f"malformed TIME literal {e.text}")
            if re.search(r"[0-9](us|ns)", e.text or "", re.I):
                self.fail(e.pos, "S0414", f"{e.text}: the units us and ns are not portable (matiec rejects "
                          "them): write fractions of ms, e.g. T#0.1ms")
            return T.TIME
        if isinstance(e, S.StringLit):
            if e.text.startswith('"'):
                self.fail(e.pos, "S0415", "WSTRING literals (\"...\") are not supported by stc: use "
                          "'...' (STRING)")
            v = _string_value(e.text[1:-1])
            if v is None:
                self.fail(e.pos, "S0416", f"invalid $ escape in string literal {e.text}")
            if len(v) > T.STR_MAX:
                self.warn(e.pos, "W0004", f"string literal of {len(v)} characters: a STRING holds "
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
                            self.fail(e.pos, "S0417", f"'{e.name}' is a value of several enumerated types: "
                                      f"write {ets[0].name}#{e.name}")
                    e.enum_value = (et, et.values.index(e.name))
                    return et
                if e.name in self.p.pous or e.name in T.STD_FBS:
                    self.fail(e.pos, "S0418", f"'{e.name}' is a POU, not a variable")
                self.fail(e.pos, "S0402", f"unknown variable '{e.name}'")
            e.var = v
            return v.type
        if isinstance(e, S.Field):
            if isinstance(e.base, S.Name) and self.dialect.enum_qualified_values \
                    and e.base.name not in self.scope \
                    and self.p.types.get(e.base.name) is not None \
                    and self.p.types[e.base.name].is_enum:
                # Enum.Value (the vendor dialects; CODESYS's qualified_only enumerations)
                et = self.p.types[e.base.name]
                if e.name not in et.values:
                    self.fail(e.pos, "S0111", f"'{e.name}' is not a value of {et.name}")
                e.enum_value = (et, et.values.index(e.name))
                return et
            bt = self.expr(e.base, None)
            if bt.is_fb:
                return self.fb_member(e, bt)
            if bt.is_struct:
                f = bt.fields.get(e.name)
                if f is None:
                    self.fail(e.pos, "S0136", f"{bt.name} has no member '{e.name}'")
                return f[0]
            self.fail(e.pos, "S0419", f"'.{e.name}' on a value of type {bt} (only STRUCT members and "
                      "function block outputs have fields)")
        if isinstance(e, S.Index):
            bt = self.expr(e.base, None)
            if not bt.is_array:
                self.fail(e.pos, "S0420", f"indexing a value of type {bt}, which is not an ARRAY")
            if len(e.indexes) != len(bt.dims):
                self.fail(e.pos, "S0421", f"{bt} needs {len(bt.dims)} index(es), got {len(e.indexes)}")
            for ix, (lo, hi) in zip(e.indexes, bt.dims):
                it = self.expr(ix, None)
                if it.is_lit:
                    if it.kind != "int":
                        self.fail(ix.pos, "S0422", "array index must be an integer")
                    self.settle(ix, T.DINT)
                    v = self.const_value(ix)
                    if v is not None and not lo <= v <= hi:
                        self.err(ix.pos, "S0423", f"index {v} is out of bounds {lo}..{hi}")
                elif it.is_elem and it.kind == "bit":
                    self.err(ix.pos, "S0424", f"an array index of type {it} is not portable (matiec rejects "
                             f"it): convert it, e.g. {it.name}_TO_UINT(i)")
                elif not (it.is_elem and it.is_int):
                    self.err(ix.pos, "S0425", f"array index must be of an integer type, not {it}")
            return bt.elem
        if isinstance(e, S.BitAccess):
            self.expr(e.base, None)
            bit = e.bit.lstrip("%XxBbWwDd") if e.bit.startswith("%") else e.bit
            self.fail(e.pos, "S0426", f"bit access .{e.bit} is not portable (matiec rejects it): use "
                      f"(x AND 16#{1 << min(int(bit) if bit.isdigit() else 0, 63):X}) <> 0 to read; "
                      "OR / AND NOT masks to write")
        if isinstance(e, S.Deref):
            if not self.dialect.pointers:
                self.fail(e.pos, "S0427", "pointer dereference (^) is not portable (matiec rejects POINTER TO)")
            bt = self.expr(e.base, None)
            if not isinstance(bt, T.PointerT):
                self.fail(e.pos, "S0428", f"'^' on a value of type {bt}, which is not a POINTER TO")
            return bt.target
        if isinstance(e, S.Call):
            return self.call(e, statement=False, expected=expected)
        if isinstance(e, S.UnOp):
            return self.unop(e, expected)
        if isinstance(e, S.BinOp):
            return self.binop(e, expected)
        self.fail(e.pos, "S0429", "unsupported expression")

    def typed_lit(self, e):
        tn = e.type_name
        if e.kind == "bad":
            self.fail(e.pos, "S0430", f"invalid integer literal in {e.text}")
        if tn in self.p.types and self.p.types[tn] is not None and self.p.types[tn].is_enum:
            et = self.p.types[tn]
            if e.kind != "ident" or e.value not in et.values:
                self.fail(e.pos, "S0431", f"'{e.text}': {e.value} is not a value of {tn}")
            e.enum_value = (et, et.values.index(e.value))
            return et
        if tn in ("T", "TIME"):
            self.fail(e.pos, "S0413", f"malformed TIME literal {e.text}")
        t = T.ELEMENTARY.get(tn)
        if t is None or t.kind == "time":
            if tn in T.UNSUPPORTED_TYPES or tn in ("D", "TOD", "DT"):
                self.fail(e.pos, "S0432", f"{tn} literals are not supported by stc")
            self.fail(e.pos, "S0433", f"unknown type or enumeration '{tn}' in literal {e.text}")
        if t.kind == "bool":
            if e.kind == "bool" or e.kind == "int" and e.value in (0, 1):
                return t
            self.fail(e.pos, "S0434", f"invalid BOOL literal {e.text}")
        if t.kind == "real":
            if e.kind != "real":
                self.fail(e.pos, "S0435", f"invalid {tn} literal {e.text}")
            return t
        if e.kind != "int":
            self.fail(e.pos, "S0435", f"invalid {tn} literal {e.text}")
        if not _lit_fits(e.value, t):
            self.fail(e.pos, "S0436", f"{e.text} is out of range of {tn}")
        return t

    def unop(self, e, expected):
        t = self.expr(e.operand, expected)
        if e.op == "NOT":
            if t.is_lit:
                if t.kind != "int":
                    self.fail(e.pos, "S0437", "NOT needs BOOL or a bit string type")
                return t
            if not (t.is_elem and t.is_anybit):
                self.fail(e.pos, "S0438", f"NOT needs BOOL or a bit string type, not {t}")
            return t
        if t.is_lit:
            return t
        if e.op == "-":
            if t.is_elem and (t.kind in ("sint", "real", "time")):
                return t
            self.fail(e.pos, "S0439", f"unary minus needs a signed type, not {t}")
        if t.is_elem and t.is_num:
            return t
        self.fail(e.pos, "S0440", f"unary + needs a numeric type, not {t}")

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
            self.fail(e.pos, "S0441", f"TIME {op} {rt}: the right operand must be a number")
        if op == "*" and rt.is_elem and rt.kind == "time" and (lt.is_lit or lt.is_elem and lt.is_num):
            # matiec accepts it, but its C passes the number as the TIME argument of __time_mul
            # and does not compile (checked with iec2c): refuse it here, where the line is known
            self.fail(e.pos, "S0442", "number * TIME: matiec's generated C does not compile this order; "
                      "write TIME * number")
        if op in ("+", "-") and lt.is_elem and lt.kind == "time":
            if rt.is_elem and rt.kind == "time":
                self.note(e.pos, "time-sum", f"TIME '{op}': matiec leaves a nanosecond part of "
                          "exactly 1e9 unnormalised (it compares below the whole second)")
                return T.TIME
            self.fail(e.pos, "S0443", f"TIME {op} {rt}: both operands must be TIME (write e.g. T#5ms)")
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
                self.fail(e.pos, "S0444", f"{op} needs BOOL or a bit string type")
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
            self.fail(e.pos, "S0445", f"'{op}' between {lt} and {rt}: IEC strict typing needs the same "
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
                self.fail(e.pos, "S0446", f"cannot compare values of type {t}")
            if t.is_enum and op not in ("=", "<>"):
                self.fail(e.pos, "S0447", f"'{op}' on enumerated type {t}: only = and <> are allowed")
            return T.BOOL
        if op in self._LOGIC:
            if not (t.is_elem and t.is_anybit):
                self.fail(e.pos, "S0448", f"{op} needs BOOL or a bit string type (BYTE/WORD/DWORD/LWORD), "
                          f"not {t}")
            return t
        if t.is_elem and t.kind == "string":
            self.fail(e.pos, "S0449", f"'{op}' on STRING is not defined: use CONCAT, LEN")
        # arithmetic
        if not t.is_elem:
            self.fail(e.pos, "S0450", f"'{op}' on {t}")
        if op == "/" and t.is_int and self.const_value(e.right) == 0:
            self.fail(e.right.pos, "S0451", "division by constant zero (matiec rejects it)")
        if op == "MOD":
            if not t.is_int:
                self.fail(e.pos, "S0452", f"MOD needs an integer type, not {t}")
            return t
        if op == "**":
            if t.kind != "real":
                self.fail(e.pos, "S0453", f"'**' needs REAL or LREAL, not {t}")
            return t
        if t.kind == "time":
            if op in ("+", "-"):
                return t
            self.fail(e.pos, "S0454", f"TIME {op} TIME is not defined")
        if not t.is_num:
            self.fail(e.pos, "S0455", f"arithmetic '{op}' on {t} is not allowed (matiec rejects it: "
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
            if (e.op == "*" and matiec_time.time_mul(tv, kv) == tv * kv) or \
                    (e.op == "/" and kv != 0 and abs(tv) % 1_000_000_000 < 2**31 and
                     matiec_time.time_div(tv, kv) == int(tv / kv)):
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
            self.warn(e.pos, "W0005", "portability: TIME * number differs between matiec and IEC: matiec "
                      "scales the sub-second part through a 32-bit int of nanoseconds "
                      "(T#1ms * 2148 gives -2.147 s); build it from whole seconds and "
                      "milliseconds: T#1s * (n / 1000) + T#1ms * (n MOD 1000)")
        else:
            self.warn(e.pos, "W0006", "portability: TIME / number differs between matiec and IEC: "
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
        return all(matiec_time.time_mul(tv, k) == tv * k for k in (abs(c) - 1, 1 - abs(c))) and \
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
                self.warn(x.pos, "W0007", f"portability: the intermediate value of this {t} expression "
                          f"is not truncated to {t} by matiec (C computes it in 32-bit int) "
                          f"but is by IEC: assign it to a variable of type {t} first")
                return

    def _power(self, e, lt, rt):
        """x ** y (EXPT): x REAL or LREAL, y any number; the result has x's type."""
        if lt.is_lit:
            if lt.kind != "real":
                self.fail(e.left.pos, "S0456", "'**' needs REAL or LREAL on the left: write a REAL "
                          "literal like 2.0")
            if e.left.ty is not None and not e.left.ty.is_lit:
                lt = e.left.ty          # settled by the context already
            else:
                lt = rt if rt.is_elem and rt.kind == "real" else T.ELEMENTARY["LREAL"]
                self.settle(e.left, lt)
        if not (lt.is_elem and lt.kind == "real"):
            self.fail(e.pos, "S0453", f"'**' needs REAL or LREAL, not {lt}")
        if rt.is_lit:
            self.settle(e.right, lt if rt.kind == "real" else T.DINT)
        elif not (rt.is_elem and rt.is_num):
            self.fail(e.right.pos, "S0457", f"'**': the exponent must be a number, not {rt}")
        return lt
