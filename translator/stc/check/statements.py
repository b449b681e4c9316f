"""Bodies and statements: assignments, IF, CASE, loops, and matiec's FOR semantics."""
from .. import syntax as S
from .. import types as T
from ..diag import CompileError
from .helpers import _lit_fits


class StatementChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

    # ---- bodies
    def _body(self, pou):
        self.cur = pou
        self.scope = pou.vars
        self.loop_depth = 0
        self.for_vars = []
        if not pou.node.body:
            self.err(pou.node.pos, "S0301", f"a {pou.kind.replace('_', ' ').upper()} without statements is "
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
                self.err(s.pos, "S0302", "a FUNCTION call as a statement is not portable (matiec rejects "
                         "it): assign its result to a variable")
        elif isinstance(s, S.If):
            for cond, body in s.branches:
                self.cond(cond, "IF")
                if not body:
                    self.err(cond.pos, "S0303", "empty THEN/ELSIF branch is not portable (matiec rejects "
                             "it): add a statement or invert the condition")
                self.stmts(body)
            if s.orelse is not None:
                if not s.orelse:
                    self.err(s.pos, "S0304", "empty ELSE branch is not portable (matiec rejects it): "
                             "remove the ELSE")
                self.stmts(s.orelse)
        elif isinstance(s, S.Case):
            self.case(s)
        elif isinstance(s, S.For):
            self.for_(s)
        elif isinstance(s, S.While):
            self.cond(s.cond, "WHILE")
            if not s.body:
                self.err(s.pos, "S0305", "empty WHILE body is not portable (matiec rejects it)")
            self.loop_depth += 1
            self.stmts(s.body)
            self.loop_depth -= 1
        elif isinstance(s, S.Repeat):
            if not s.body:
                self.err(s.pos, "S0306", "empty REPEAT body is not portable (matiec rejects it)")
            self.loop_depth += 1
            self.stmts(s.body)
            self.loop_depth -= 1
            self.cond(s.cond, "UNTIL")
        elif isinstance(s, S.Exit):
            if not self.loop_depth:
                self.err(s.pos, "S0307", "EXIT outside a loop")
        elif isinstance(s, S.Continue):
            if not self.loop_depth:
                self.err(s.pos, "S0308", "CONTINUE outside a loop")
        elif isinstance(s, S.Return):
            pass
        elif isinstance(s, S.Empty):
            self.err(s.pos, "S0309", "a lone ';' (empty statement) is not portable (matiec rejects it): "
                     "remove it")
        elif isinstance(s, S.CaseLabels):
            self.err(s.pos, "S0310", "case label outside CASE")

    def cond(self, e, what):
        t = self.expr(e, T.BOOL)
        if not (t.is_elem and t.kind == "bool"):
            self.err(e.pos, "S0311", f"{what} condition must be BOOL, not {t} (write e.g. x <> 0)")

    def case(self, s):
        st = self.expr(s.selector, None)
        if st.is_lit:
            self.settle(s.selector, T.DINT)
            st = T.DINT
        if st.is_elem and st.kind == "bit":
            self.err(s.selector.pos, "S0312", f"CASE on {st} is not portable (matiec rejects it): "
                     f"convert first, e.g. CASE {st.name}_TO_UINT(x) OF")
        elif not (st.is_enum or st.is_elem and st.is_int):
            self.err(s.selector.pos, "S0313", f"CASE selector must be an integer or enumerated type, not {st}")
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
                                     "S0314", f"empty case range {vlo}..{vhi}")
                        for a, b in seen:
                            if not (vhi < a or vlo > b):
                                self.err(item.pos, "S0315", "case label value already used")
                                break
                        seen.append((vlo, vhi))
            else:
                if cur is None:
                    self.err(item.pos, "S0316", "statement before the first case label")
                    continue
                cur[1].append(item)
        s.groups = groups
        self.stmts([x for _, body in groups for x in body])
        for labels, body in groups:
            if not body:
                self.err(labels.pos, "S0317", "empty case branch is not portable (matiec rejects it): "
                         "add a statement")
        if s.orelse is not None:
            if not s.orelse:
                self.err(s.pos, "S0304", "empty ELSE branch is not portable (matiec rejects it): remove the ELSE")
            self.stmts(s.orelse)
        s.sel_type = st

    def case_label(self, lab, st):
        """Return the integer value of a case label (enum: its index)."""
        if lab is None:
            self.err(None, "S0318", "invalid integer case label")
            return None
        if isinstance(lab, int):
            if st is not None and st.is_enum:
                self.err(None, "S0319", "integer label in CASE on enumeration")
                return None
            if st is not None and st.is_elem and not _lit_fits(lab, st):
                self.err(None, "S0320", f"case label {lab} out of range of {st}")
            return lab
        pos = lab.pos
        if isinstance(lab, S.IntLit):
            self.err(pos, "S0321", f"hexadecimal/based case labels ({lab.text}) are not portable (matiec "
                     f"rejects them): write the decimal value {lab.value}")
            return None
        if isinstance(lab, S.TypedLit):
            if lab.kind == "ident":
                return self.enum_label(lab.type_name, lab.value, pos, st)
            self.err(pos, "S0322", f"typed case labels ({lab.text}) are not portable (matiec rejects them): "
                     f"write the plain decimal value")
            return None
        if isinstance(lab, S.Name):
            if st is not None and st.is_enum:
                if lab.name in st.values:
                    return st.code(lab.name)
                self.err(pos, "S0111", f"'{lab.name}' is not a value of {st.name}")
                return None
            self.err(pos, "S0323", f"named constants as case labels ('{lab.name}') are not portable "
                     "(matiec rejects them): write the decimal value")
            return None
        return None

    def enum_label(self, tname, vname, pos, st):
        et = self.p.types.get(tname)
        if et is None or not et.is_enum:
            self.err(pos, "S0324", f"'{tname}' is not an enumerated type")
            return None
        if vname not in et.values:
            self.err(pos, "S0111", f"'{vname}' is not a value of {tname}")
            return None
        if st is not None and not (st.is_enum and st.name == et.name):
            self.err(pos, "S0325", f"label of type {et.name} in CASE on {st}")
            return None
        return et.code(vname)

    def for_(self, s):
        v = self.lookup(s.var)
        vt = v.type
        s.var.ty = vt
        s.var.var = v
        if not (vt.is_elem and vt.is_int):
            self.err(s.var.pos, "S0326", f"FOR variable must be of an integer type, not {vt}")
        if v.constant:
            self.err(s.var.pos, "S0327", f"'{v.name}' is CONSTANT")
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
            self.err(s.pos, "S0328", "empty FOR body is not portable (matiec rejects it)")
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
                self.warn(s.pos, "W0002", "portability: this FOR runs once in IEC and OpenPLC's matiec "
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
            self.warn(s.pos, "W0003", f"portability: this FOR steps {s.var.name} past the limit of {vt} "
                      f"after its last pass: OpenPLC's matiec fork wraps it and loops forever "
                      f"(stc and upstream matiec stop); use a wider variable or EXIT")
