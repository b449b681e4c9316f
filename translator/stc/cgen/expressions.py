"""Expressions: lvalues, array indices, operators, TIME arithmetic, conversions, standard functions."""
from functools import reduce

from .. import matiec_time
from .. import syntax as S
from .. import types as T
from .helpers import _c_elem, _const, _wide, lit


class ExpressionGen:
    """A part of Gen (cgen/__init__.py): its methods call the other parts' through self."""
    # ---- expressions
    def lv(self, e):
        """C lvalue of a variable expression (TIME storage is stc_time)."""
        if isinstance(e, S.Paren):
            return self.lv(e.inner)
        if isinstance(e, S.Name):
            return self.var_access(e.var)
        if isinstance(e, S.Field):
            return f"{self.lv(e.base)}.{e.name}"
        if isinstance(e, S.Index):
            bt = e.base.ty
            out = self.lv(e.base)
            for ix, (lo, hi) in zip(e.indexes, bt.dims):
                out += f"[{self.index(ix, lo, hi)}]"
            return out
        if isinstance(e, S.Deref):
            return f"(*({_c_elem(e.ty)} *)({self.ex(e.base)}))"
        raise AssertionError(f"not an lvalue: {e!r}")

    def index(self, ix, lo, hi):
        v = _const(ix)
        if v is not None and lo <= v <= hi:
            return str(v - lo)
        t = ix.ty
        fn = "stc_idxu" if t.is_elem and t.kind == "uint" and t.bits == 64 else "stc_idx"
        return f"{fn}({self.ex(ix)}, {lo}, {hi})"

    def _is_narrow(self, t):
        """matiec mode: C evaluates 8- and 16-bit integer arithmetic in int (32 bits) and only
        truncates where the value is stored or passed on; such expressions are 'wide'."""
        return self.dialect.narrow_int_in_c_int and t is not None and t.is_elem and t.kind in ("sint", "uint", "bit") \
            and t.bits < 32

    def ex(self, e, wide=False):
        """C expression of e. With wide=True (operands of operators) a narrow integer
        expression may stay in int as matiec's C leaves it; otherwise it is truncated."""
        if isinstance(e, S.Paren):
            return self.ex(e.inner, wide)
        if isinstance(e, (S.BinOp, S.UnOp)):
            r = self.binop(e) if isinstance(e, S.BinOp) else self.unop(e)
            if getattr(e, "wide", False) and not wide:
                return f"(({e.ty.ctype}){r})"
            return r
        return self._ex(e)

    def _ex(self, e):
        t = e.ty
        if isinstance(e, S.RealLit) and self.dialect.real_as_c and t.kind == "real":
            # matiec prints an untyped real literal as it is written: a C double, so the
            # operation it takes part in is computed in double (0.1 + 0.2 > 0.3 on REALs is
            # TRUE); a typed REAL#0.3 is (float)0.3
            return lit(e.value, T.ELEMENTARY["LREAL"])
        if isinstance(e, (S.IntLit, S.RealLit, S.BoolLit)):
            return lit(e.value, t)
        if isinstance(e, S.StringLit):
            return lit(e.value, t)
        if isinstance(e, S.TimeLit):
            comps = matiec_time.literal_parts(e.text) if self.dialect.time_as_pair else None
            if comps is not None:
                # as matiec's __time_to_timespec: T#1ms is 999999 ns there
                return f"stc_mt_lit({', '.join(comps)})"
            return self.tval(lit(e.ns, T.TIME))
        if isinstance(e, S.TypedLit):
            if getattr(e, "enum_value", None):
                et, _ = e.enum_value
                return f"{et.name}__{e.value}"
            return lit(e.value, t)
        if isinstance(e, (S.Name, S.Field)) and getattr(e, "enum_value", None):
            et, _ = e.enum_value
            return f"{et.name}__{e.name}"
        if isinstance(e, (S.Name, S.Field, S.Index, S.Deref)):
            lv = self.lv(e)
            if t.is_elem and t.kind == "time" and not self.dialect.time_as_pair:
                return f"stc_time_ns({lv})"
            return lv
        if isinstance(e, S.UnOp):
            return self.unop(e)
        if isinstance(e, S.BinOp):
            return self.binop(e)
        if isinstance(e, S.Call):
            k = e.kind
            if k == "func":
                call = self.func_call(e)
                rt = e.pou.rtype
                if rt.is_elem and rt.kind == "time" and not self.dialect.time_as_pair:
                    return f"stc_time_ns({call})"
                return call
            if k == "conv":
                return self.conversion(e)
            if k == "vendor":
                return self.vendor_call(e)
            if k == "binop":
                r = self.binop(e.binop)    # ADD(a, b) ...: a typed function in matiec
                return f"(({t.ctype}){r})" if getattr(e.binop, "wide", False) else r
            if k == "math":
                xs = [f"(double){self.fex(a)}" for a in e.argv]
                fn = {"SQRT": "sqrt", "LN": "log", "LOG": "log10", "EXP": "exp",
                      "EXPT": "stc_expt", "SIN": "sin", "COS": "cos", "TAN": "tan",
                      "ASIN": "asin", "ACOS": "acos", "ATAN": "atan"}[e.name]
                return f"(({t.ctype}){fn}({', '.join(xs)}))"
            if k == "trunc":
                x = self.ex(e.argv[0])
                lo, hi = t.range()
                if t.kind == "sint":
                    return f"(({t.ctype})stc_trunc_i64({x}, {lit(lo, T.LINT)}, {lit(hi, T.LINT)}))"
                return f"(({t.ctype})stc_trunc_u64({x}, UINT64_C({hi})))"
            r = self.std_call(e)
            if self.dialect.real_as_c and t is not None and t.is_elem and t.kind == "real" and t.bits == 32:
                r = f"((float){r})"     # matiec's typed function returns a REAL
            return r
        raise AssertionError(f"cannot generate {e!r}")

    def fex(self, e):
        """C expression of an argument of a standard function: matiec passes it as the
        function's parameter type, so a REAL computed in double (an untyped real literal in
        it) is rounded to float first."""
        x = self.ex(e)
        t = e.ty
        if self.dialect.real_as_c and t is not None and t.is_elem and t.kind == "real" and t.bits == 32:
            return f"((float){x})"
        return x

    def tval(self, ns):
        """A TIME expression from C int64_t nanoseconds `ns`: the same in IEC mode; in the
        matiec modes TIME expressions are stc_time pairs, as matiec's (so sums it leaves
        unnormalised compare as they do there)."""
        return f"stc_mt_of({ns})" if self.dialect.time_as_pair else ns

    def tns(self, x):
        """int64_t nanoseconds of the C TIME expression x."""
        return f"stc_time_ns({x})" if self.dialect.time_as_pair else x

    def unop(self, e):
        t = e.ty
        x = self.ex(e.operand, wide=self._is_narrow(t))
        if self._is_narrow(t) and not (e.op == "NOT" and t.kind == "bool"):
            e.wide = True
            if e.op == "NOT":
                return f"(~(int32_t){x})"
            if e.op == "+":
                return f"((int32_t){x})"
            return f"((int32_t)(0u - (uint32_t){x}))"
        if e.op == "NOT":
            if t.kind == "bool":
                return f"(!{x})"
            return f"(({t.ctype})~{x})"
        if e.op == "+":
            return x
        if t.kind == "real":
            return f"(-{x})"
        if t.kind == "time":
            return self.tval(f"((int64_t)(0u - (uint64_t){self.tns(x)}))")
        if t.bits <= 16:
            return f"(({t.ctype})-{x})"
        return f"(({t.ctype})(0u - ({_wide(t)}){x}))"

    _COP = {"=", "<>", "<", ">", "<=", ">="}

    def binop(self, e):
        op = e.op
        t = e.ty
        if op in self._COP:
            nw = self._is_narrow(e.left.ty)
        else:
            nw = self._is_narrow(t)
        if getattr(e, "fn_form", False):
            nw = False            # ADD(a, b) ...: typed arguments and result, as in matiec
        a = self.ex(e.left, wide=nw)
        b = self.ex(e.right, wide=nw)
        if nw and op not in self._COP:
            # matiec: C int arithmetic, no truncation until the value is stored
            e.wide = True
            if op == "/":
                return f"stc_div_DINT((int32_t){a}, (int32_t){b})"
            if op == "MOD":
                return f"stc_mod_DINT((int32_t){a}, (int32_t){b})"
            if op in ("AND", "OR", "XOR"):
                cop = {"AND": "&", "OR": "|", "XOR": "^"}[op]
                return f"((int32_t){a} {cop} (int32_t){b})"
            return f"((int32_t)((uint32_t){a} {op} (uint32_t){b}))"
        if op in self._COP and e.left.ty.is_elem and e.left.ty.kind == "string":
            cop = {"=": "==", "<>": "!="}.get(op, op)
            return f"(stc_str_cmp(&{a}, &{b}) {cop} 0)" if isinstance(e.left, (S.Name, S.Field, S.Index)) \
                and isinstance(e.right, (S.Name, S.Field, S.Index)) else \
                f"(stc_str_cmpv({a}, {b}) {cop} 0)"
        if op in self._COP and self.dialect.time_as_pair and e.left.ty.is_elem and e.left.ty.kind == "time":
            # matiec compares tv_sec first, then tv_nsec (an unnormalised sum compares as such)
            cop = {"=": "==", "<>": "!="}.get(op, op)
            return f"(stc_mt_cmp({a}, {b}) {cop} 0)"
        if op in self._COP:
            ot = e.left.ty
            fam = "f" if ot.is_elem and ot.kind == "real" else \
                "u" if ot.is_elem and ot.kind in ("uint", "bit") and ot.bits == 64 else "i"
            name = {"=": "eq", "<>": "ne", "<": "lt", ">": "gt", "<=": "le", ">=": "ge"}[op]
            return f"stc_{name}_{fam}({a}, {b})"
        if op in ("AND", "OR", "XOR"):
            cop = {"AND": "&", "OR": "|", "XOR": "^"}[op]
            if t.kind == "bool":
                return f"({a} {cop} {b})"
            return f"(({t.ctype})({a} {cop} {b}))"
        if t.kind == "time":
            rt = e.right.ty           # TIME op number: the checker refuses number * TIME
            if self.dialect.time_as_pair:
                # matiec's library: pairs added and normalised in one step; scaled in double
                fn = {"+": "add", "-": "sub", "*": "mul", "/": "div"}[op]
                return f"stc_mt_{fn}({a}, {b})" if op in ("+", "-") else f"stc_mt_{fn}({a}, (double){b})"
            if op in ("+", "-"):
                return f"((int64_t)((uint64_t){a} {op} (uint64_t){b}))"
            if rt.kind == "real":
                return f"stc_time_{'mulf' if op == '*' else 'divf'}({a}, (double){b})"
            return f"stc_time_{'mul' if op == '*' else 'div'}({a}, (int64_t){b})"
        if t.kind == "real":
            if op == "MOD":
                return "0"
            if op == "**":
                return f"(({t.ctype})stc_expt((double){a}, (double){b}))"
            return f"({a} {op} {b})"
        if op == "/":
            return f"stc_div_{t.name}({a}, {b})"
        if op == "MOD":
            return f"stc_mod_{t.name}({a}, {b})"
        w = _wide(t)
        return f"(({t.ctype})(({w}){a} {op} ({w}){b}))"

    def conversion(self, e):
        src, dst = e.conv
        x = self.fex(e.args[0].value)
        if dst.kind == "string":
            # matiec: TRUE/FALSE, %lld, %llu, 16#%llx for bit strings, %.10g for REAL/LREAL
            fn = {"bool": "bool", "sint": "i", "uint": "u", "bit": "bits", "real": "real"}[src.kind]
            return f"stc_str_of_{fn}({x})"
        if src.kind == "string":
            if dst.kind == "bool":
                return f"stc_str_to_bool({x})"
            if dst.kind == "real":
                return f"(({dst.ctype})stc_str_to_real({x}))"
            return f"(({dst.ctype})stc_str_to_i({x}))"
        if dst.kind == "bool" and src.kind == "time" and self.dialect.time_as_pair:
            return f"(({x}).tv_sec != 0 || ({x}).tv_nsec != 0)"
        if dst.kind == "bool":
            return f"({x} != 0)"
        if src.kind == "time" and self.dialect.time_as_pair:
            if dst.kind == "real":
                return f"(({dst.ctype})((double)({x}).tv_sec + (double)({x}).tv_nsec / 1e9))"
            return f"(({dst.ctype})({x}).tv_sec)"
        if dst.kind == "time" and self.dialect.time_as_pair:
            if src.kind == "real":
                return f"stc_mt_of_real((double){x})"
            return f"stc_mt((long)({x}), 0)"
        if src.kind == "time":
            # matiec converts TIME to numbers in whole seconds (tv_sec); stc does the same
            if dst.kind == "real":
                return f"(({dst.ctype})((double){x} / 1e9))"
            return f"(({dst.ctype})({x} / 1000000000))"
        if dst.kind == "time":
            if src.kind == "real":
                return f"((int64_t)((double){x} * 1e9))"
            return f"((int64_t)((uint64_t)(int64_t){x} * UINT64_C(1000000000)))" if src.kind != "uint" or src.bits < 64 \
                else f"((int64_t)((uint64_t){x} * UINT64_C(1000000000)))"
        if src.kind == "real" and dst.kind != "real":
            lo, hi = dst.range()
            if dst.kind == "sint":
                return f"(({dst.ctype})stc_real_to_i64({x}, {lit(lo, T.LINT)}, {lit(hi, T.LINT)}))"
            return f"(({dst.ctype})stc_real_to_u64({x}, UINT64_C({hi})))"
        return f"(({dst.ctype}){x})"

    def std_call(self, e):
        n = e.name
        args = e.argv
        t = e.ty
        xs = [self.fex(a) for a in args]
        if n in ("SHL", "SHR", "ROL", "ROR"):
            if self.dialect.shift_count_modulo and n in ("SHL", "SHR") and t.bits > 1:
                # matiec shifts in C: x86 takes the count modulo 32 (64 for LWORD), after the
                # promotion of BYTE and WORD to int
                mask = 63 if t.bits == 64 else 31
                return f"stc_{n.lower()}_{t.name}({xs[0]}, (int64_t){xs[1]} & {mask})"
            return f"stc_{n.lower()}_{t.name}({xs[0]}, (int64_t){xs[1]})"
        if n == "LEN":
            return f"(({t.ctype}){xs[0]}.len)"
        if n in T.STR_FUNCS:
            cargs = [x if k.startswith("IN") else f"(int64_t){x}"
                     for k, x in zip(T.STR_FUNCS[n], xs)]
            r = f"stc_str_{n.lower()}({', '.join(cargs)})"
            return f"(({t.ctype}){r})" if n == "FIND" else r
        if n == "CONCAT":
            out = xs[0]
            for x in xs[1:]:
                out = f"stc_str_concat({out}, {x})"
            return out
        if n == "ABS":
            if t.kind == "uint":
                return xs[0]
            if t.kind == "real":
                return f"({xs[0]} < 0 ? -{xs[0]} : {xs[0]})"
            return f"(({t.ctype})({xs[0]} < 0 ? ({t.ctype})(0u - ({_wide(t)}){xs[0]}) : {xs[0]}))"
        if n == "MOVE":
            return xs[0]
        if n in ("MIN", "MAX"):
            cmp = "<" if n == "MIN" else ">"
            return reduce(lambda acc, x: f"stc_{n.lower()}_pick({acc}, {x})", xs) if False else \
                self._minmax(xs, cmp, t)
        if n == "LIMIT":
            mn, x, mx = xs
            return self._minmax([self._minmax([x, mn], ">", t), mx], "<", t)
        if n == "SEL":
            return f"({xs[0]} ? {xs[2]} : {xs[1]})"
        if n == "MUX":
            k = xs[0]
            out = xs[-1]
            last = len(xs) - 1
            if self.dialect.mux_out_of_range_zero:
                # matiec: a selector outside 0..n-1 gives the type's initial value (0)
                out = f"({k} == {last - 1} ? {xs[-1]} : {self._zero(t)})"
            for i in range(len(xs) - 2, 0, -1):
                out = f"({k} == {i - 1} ? {xs[i]} : {out})"
            return out
        raise AssertionError(n)

    def _zero(self, t):
        if t.is_enum:
            return "0"
        if not t.is_elem:
            return f"({_c_elem(t)}){{0}}"
        if t.kind == "time":
            return self.tval("INT64_C(0)")
        return lit(0, t)

    def _minmax(self, xs, cmp, t):
        # nested conditional expressions; arguments are evaluated more than once, which is
        # harmless because ST expressions (without FB calls) have no side effects except
        # function outputs, and those functions are called through temporaries below.
        fam = "f" if t.kind == "real" else "u" if t.kind in ("uint", "bit") and t.bits == 64 else "i"
        fn = f"stc_{'lt' if cmp == '<' else 'gt'}_{fam}"
        out = xs[0]
        for x in xs[1:]:
            if self.dialect.time_as_pair and t.is_elem and t.kind == "time":
                out = f"((stc_mt_cmp({out}, {x}) {cmp} 0) ? {out} : {x})"
            else:
                out = f"({fn}({out}, {x}) ? {out} : {x})"
        return out
