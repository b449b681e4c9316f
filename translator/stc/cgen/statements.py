"""Statements: assignments, IF, CASE, loops, stores."""
from .. import syntax as S
from .helpers import _balanced, _body_eno, _wide, cdecl, lit


class StatementGen:
    """A part of Gen (cgen/__init__.py): its methods call the other parts' through self."""

    def new_tmp(self, base):
        self.tmp += 1
        return f"{base}{self.tmp}__"

    # ---- statements
    def stmts(self, lst):
        for s in lst:
            self.stmt(s)

    def block(self, head, body):
        """The line head (it opens a C block), then the statements of body one level in."""
        self.w(head)
        self.ind += 1
        self.stmts(body)
        self.ind -= 1

    def stmt(self, s):
        if isinstance(s, S.Assign):
            self.store(self.lv(s.target), s.target.ty, s.value)
        elif isinstance(s, S.CallStmt):
            self.call_stmt(s)
        elif isinstance(s, S.If):
            first = True
            for cond, body in s.branches:
                self.block(f"{'if' if first else '} else if'} ({self.cond(cond)}) {{", body)
                first = False
            if s.orelse:
                self.block("} else {", s.orelse)
            self.w("}")
        elif isinstance(s, S.Case):
            self.case(s)
        elif isinstance(s, S.For):
            self.for_(s)
        elif isinstance(s, S.While):
            self.w(f"while ({self.cond(s.cond)}) {{")
            self.ind += 1
            self.stmts(s.body)
            self.ind -= 1
            self.w("}")
        elif isinstance(s, S.Repeat):
            self.w("do {")
            self.ind += 1
            self.stmts(s.body)
            self.ind -= 1
            self.w(f"}} while (!({self.ex(s.cond)}));")
        elif isinstance(s, S.Exit):
            self.w("break;")
        elif isinstance(s, S.Continue):
            self.w("continue;")
        elif isinstance(s, S.Return):
            if self.pou.kind == "function" and _body_eno(self.pou):
                self.w("*ENO__p = ENO;")
            if self.pou.kind == "function" and not self.pou.rtype.is_array:
                self.w(f"return {self.pou.name}__RESULT;")
            else:
                self.w("return;")

    def cond(self, e):
        """A condition without redundant outer parentheses (clang warns on `if ((a == b))`)."""
        c = self.ex(e)
        while c.startswith("(") and c.endswith(")") and _balanced(c[1:-1]):
            c = c[1:-1]
        return c

    def case(self, s):
        st = s.sel_type
        sel = self.new_tmp("sel")
        ctype = "uint64_t" if st.is_elem and st.kind == "uint" and st.bits == 64 else "int64_t"
        self.w("{")
        self.ind += 1
        # matiec stores the selector in a variable of its type first (INT __case_expression),
        # so an 8/16-bit selector is truncated there, as it is in IEC semantics
        self.w(f"{ctype} {sel} = {self.ex(s.selector)};")
        first = True
        for labels, body in s.groups:
            conds = []
            for lo, hi in labels.labels:
                a = self.label_value(lo, st)
                fam = "u" if ctype == "uint64_t" else "i"
                if hi is None:
                    conds.append(f"{sel} == {self.case_lit(a, ctype)}")
                else:
                    b = self.label_value(hi, st)
                    conds.append(f"(stc_ge_{fam}({sel}, {self.case_lit(a, ctype)}) && "
                                 f"stc_le_{fam}({sel}, {self.case_lit(b, ctype)}))")
            self.block(f"{'if' if first else '} else if'} ({' || '.join(conds)}) {{", body)
            first = False
        if s.orelse:
            self.block("{" if first else "} else {", s.orelse)
        if not first or s.orelse:
            self.w("}")
        else:
            self.w(f"(void){sel};")
        self.ind -= 1
        self.w("}")

    def case_lit(self, v, ctype):
        if ctype == "uint64_t":
            return f"UINT64_C({v})"
        if v == -(1 << 63):
            return "(-INT64_C(9223372036854775807) - 1)"
        return f"INT64_C({v})" if v >= 0 else f"(-INT64_C({-v}))"

    def label_value(self, lab, st):
        if isinstance(lab, int):
            return lab
        if isinstance(lab, S.TypedLit):
            return st.code(lab.value)
        if isinstance(lab, S.Name):
            return st.code(lab.name)
        return 0

    def for_(self, s):
        v = s.var.var
        t = v.type
        cv = self.var_access(v)
        n = self.new_tmp("n")
        step = self.ex(s.step) if s.step is not None else lit(1, t)
        end = self.new_tmp("end")
        by = self.new_tmp("by")
        self.w("{")
        self.ind += 1
        self.w(f"{cdecl(t, end)};")
        self.w(f"{cdecl(t, by)};")
        self.w(f"uint64_t {n};")
        self.w(f"{cv} = {self.ex(s.start)};")
        self.w(f"{end} = {self.ex(s.end)};")
        self.w(f"{by} = {step};")
        u64 = t.kind == "uint" and t.bits == 64
        fn = "stc_for_count_u" if u64 else "stc_for_count"
        inc = f"{cv} = ({t.ctype})({_wide(t)})({cv} + ({_wide(t)}){by})"
        if self.dialect.for_matiec_upstream:
            # upstream matiec: no pass unless the first test holds; the increment comes before
            # the next pass's body, so the variable keeps the last value
            first = f"{'stc_for_first_up_u' if u64 else 'stc_for_first_up'}({cv}, {end}, {by}, " \
                    f"{0 if s.step is None else 1})"
            self.w(f"for ({n} = {first} ? {fn}({cv}, {end}, {by}) : 0u; {n} > 0u; "
                   f"{n}--, ({n} > 0u ? (void)({inc}) : (void)0)) {{")
        else:
            self.w(f"for ({n} = {fn}({cv}, {end}, {by}); {n} > 0u; {n}--, {inc}) {{")
        self.ind += 1
        self.stmts(s.body)
        self.ind -= 1
        self.w("}")
        self.ind -= 1
        self.w("}")

    def var_access(self, v):
        if v.kind == "RESULT":
            return self.acc["\0result"]
        return self.acc[v.name]

    def store(self, lv, t, value):
        """Assignment of expression `value` to storage lv of type t."""
        if t.is_array and isinstance(value, S.Call) and getattr(value, "kind", None) == "func":
            # a FUNCTION returning an array writes into a temporary, then it is copied (the
            # function may read the target through a global)
            tmp = self.new_tmp("res")
            self.w(f"{{ {t.name} {tmp}; {self.func_call(value, result=tmp)}; "
                   f"memcpy(&{lv}, &{tmp}, sizeof {lv}); }}")
        elif t.is_array:
            self.w(f"memcpy(&{lv}, &{self.lv(value)}, sizeof {lv});")
        elif t.is_struct:
            self.w(f"{lv} = {self.ex(value)};")
        elif t.is_elem and t.kind == "time":
            self.w(f"{lv} = {self.ex(value)};" if self.dialect.time_as_pair else f"{lv} = stc_time_of({self.ex(value)});")
        else:
            self.w(f"{lv} = {self.ex(value)};")
