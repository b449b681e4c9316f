"""Calls of functions and function blocks: argument binding, vendor functions, conversions."""
from .. import syntax as S
from .. import types as T
from ..diag import CompileError
from .helpers import _VENDOR_FUNCS, _conversion, _int_result, _is_false, _is_variable, _strip_paren


class CallChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

    # ---- calls
    def call(self, c, statement, expected=None):
        name = c.name
        v = self.scope.get(name)
        if v is not None:
            if not v.type.is_fb:
                self.fail(c.pos, "S0601", f"'{name}' is a variable of type {v.type}, not a function block "
                          "instance")
            if not statement:
                self.fail(c.pos, "S0602", f"function block instance '{name}' cannot be called in an "
                          f"expression: call it as a statement and read {name}.Q")
            c.kind = "fb"
            c.var = v
            self.bind_args(c, v.type.pou, fb=True)
            for pn, pv in v.type.pou.vars.items():
                if pv.kind == "VAR_IN_OUT" and pv.type.is_fb and pn not in c.bound:
                    # (vendor dialects only: an FB in-out is a reference, as CODESYS's rClient)
                    self.err(c.pos, "S0603", f"{pn}, a VAR_IN_OUT of {v.type.pou.name}, must be given in "
                             "every call (the IDEs require it; unbound it refers to nothing)")
            self._warn_std_fb(c, v.type.pou)
            return None
        if name in T.STD_FBS or (name in self.p.pous and self.p.pous[name].kind == "function_block"):
            self.fail(c.pos, "S0604", f"'{name}' is a function block type: declare an instance and call that")
        if name in self.p.pous:
            pou = self.p.pous[name]
            if pou.kind != "function":
                self.fail(c.pos, "S0605", f"'{name}' is a {pou.kind.replace('_', ' ').upper()}, which cannot be called")
            if self.cur is not None and pou is self.cur:
                self.fail(c.pos, "S0606", "recursion is not allowed in IEC 61131-3")
            c.kind = "func"
            c.pou = pou
            if not c.args:
                self.fail(c.pos, "S0607", f"calling a FUNCTION without arguments ({name}()) is not portable "
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
        if name in _VENDOR_FUNCS and self.dialect.address_functions:
            return self.vendor_func(c)
        if name.startswith("TO_") and self.dialect.enum_to_number and name[3:] in T.ELEMENTARY \
                and T.ELEMENTARY[name[3:]].kind in ("sint", "uint", "bit") and len(c.args) == 1 \
                and isinstance(c.args[0], S.ArgPos):
            # TO_WORD(eErrorID): the number of an enumerated value (CODESYS)
            at = self.expr(c.args[0].value, None)
            if not at.is_enum:
                self.fail(c.pos, "S0608", f"{name} of a {at} is not supported: use a typed conversion "
                          f"({at}_TO_{name[3:]})")
            c.kind = "vendor"
            c.argv = [c.args[0].value]
            return T.ELEMENTARY[name[3:]]
        if name.startswith("TO_"):
            self.fail(c.pos, "S0609", f"generic conversion {name} is not portable (matiec rejects it): "
                      "use a typed conversion like INT_TO_UINT")
        self.fail(c.pos, "S0610", f"unknown function '{name}'")

    def vendor_func(self, c):
        """ADR(x), SIZEOF(x) and MEMCPY(destAddr, srcAddr, n) of the TwinCAT / CODESYS
        dialects (Tc2_System MEMCPY; CODESYS SysMemCpy(pDest, pSrc, udiCount))."""
        n = c.name
        names = _VENDOR_FUNCS[n]
        args = [None] * len(names)
        for i, a in enumerate(c.args):
            if isinstance(a, S.ArgPos) and all(x is None for x in args[i:]):
                if i >= len(names):
                    self.fail(a.pos, "S0611", f"{n} takes {len(names)} argument(s)")
                args[i] = a.value
            elif isinstance(a, S.ArgIn) and a.name in names:
                args[names.index(a.name)] = a.value
            else:
                self.fail(a.pos, "S0612", f"{n}: arguments are {', '.join(names)}")
        if any(x is None for x in args):
            self.fail(c.pos, "S0613", f"{n} needs {', '.join(names)}")
        c.kind = "vendor"
        c.argv = args
        if n in ("ADR", "SIZEOF"):
            x = args[0]
            if not _is_variable(x) and not isinstance(x, S.Deref):
                self.fail(x.pos, "S0614", f"{n} takes a variable")
            t = self.expr(x, None)
            if t.is_fb:
                self.fail(x.pos, "S0615", f"{n} of a function block instance is not supported")
            return T.PointerT(t) if n == "ADR" else T.ELEMENTARY["UDINT"]
        for x in args[:2]:
            t = self.expr(x, None)
            if not isinstance(t, T.PointerT):
                self.fail(x.pos, "S0616", f"{n}: an address (ADR(...) or a POINTER), not {t}")
        t = self.expr(args[2], T.ELEMENTARY["UDINT"])
        self.coerce(args[2], t, T.ELEMENTARY["UDINT"], f"{n}'s byte count")
        return T.ELEMENTARY["UDINT"]

    def _warn_std_fb(self, c, pou):
        std = pou.std.name if pou.std is not None else None
        if std == "F_TRIG":
            clk = c.bound.get("CLK")
            if not (isinstance(clk, S.BoolLit) and clk.value):
                self.warn(c.pos, "W0009", "portability: F_TRIG differs between matiec and the OpenPLC "
                          "fork / IEC mode on the first call: matiec gives Q = TRUE when CLK is "
                          "FALSE on the first call; ignore Q on the first scan")
        elif std in ("TON", "TOF", "TP"):
            pt = c.bound.get("PT")
            k = _strip_paren(pt).ns if isinstance(_strip_paren(pt), S.TimeLit) else None
            if k is not None and k <= 0:
                self.warn(pt.pos, "W0010", f"portability: {std} with PT = T#0s differs between matiec and "
                          "IEC: matiec's Q changes one call late (it compares from the call after "
                          "the edge)")
            elif k is None and not _is_false(c.bound.get("IN")):
                self.note(c.pos, "timer-pt", f"{std} with a PT that is not a constant: at "
                          "T#0s matiec's Q changes one call late")
        elif std in ("CTU", "CTD", "CTUD"):
            self.warn(c.pos, "W0011", f"portability: {std} differs between matiec and IEC at its limits: "
                      "matiec stops counting up at PV and down at 0, IEC at the limits of INT")

    def bind_args(self, c, pou, fb):
        params = [v for v in pou.vars.values() if v.kind in ("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT")]
        inputs = [v for v in params if v.kind in ("VAR_INPUT", "VAR_IN_OUT")]
        bound = {}
        outs = []
        positional = [a for a in c.args if isinstance(a, S.ArgPos)]
        named = [a for a in c.args if not isinstance(a, S.ArgPos)]
        if positional and named:
            self.fail(c.pos, "S0617", "mixing positional and named (:=) arguments is not allowed")
        if positional:
            if len(positional) > len(inputs):
                self.fail(c.pos, "S0618", f"{pou.name} takes {len(inputs)} inputs, got {len(positional)}")
            for a, p in zip(positional, inputs):
                bound[p.name] = a.value
        c.en = c.eno = None
        for a in named:
            if a.name in ("EN", "ENO") and isinstance(a, S.ArgIn if a.name == "EN" else S.ArgOut):
                if not fb and pou.rtype is not None and not pou.rtype.is_elem and not pou.rtype.is_enum:
                    self.err(a.pos, "S0619", f"EN/ENO on a call of {pou.name}, which returns {pou.rtype}, "
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
                        self.err(a.pos, "S0620", "NOT x => y is not supported: negate afterwards")
                        continue
                    tt = self.lvalue(a.target, "assign to")
                    if not T.same_type(tt, T.BOOL):
                        self.err(a.target.pos, "S0621", f"ENO is BOOL but '=>' target is {tt}")
                    c.eno = a.target
                continue
            p = pou.vars.get(a.name)
            if p is None or p.kind not in ("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT"):
                self.err(a.pos, "S0622", f"{pou.name} has no parameter '{a.name}'")
                continue
            if isinstance(a, S.ArgIn):
                if p.kind == "VAR_OUTPUT":
                    self.err(a.pos, "S0623", f"'{a.name}' is an output of {pou.name}: use {a.name} => variable")
                    continue
                if a.name in bound:
                    self.err(a.pos, "S0624", f"parameter '{a.name}' given twice")
                bound[a.name] = a.value
            else:
                if p.kind != "VAR_OUTPUT":
                    self.err(a.pos, "S0625", f"'{a.name}' is not an output of {pou.name}: use {a.name} := value")
                    continue
                if a.negate:
                    self.err(a.pos, "S0620", "NOT x => y is not supported: negate afterwards")
                    continue
                tt = self.lvalue(a.target, "assign to")
                if not T.same_type(p.type, tt):
                    self.err(a.target.pos, "S0626", f"output {a.name} is {p.type} but '=> ' target is {tt}")
                outs.append((p, a.target))
        c.bound = {}
        for p in inputs:
            e = bound.get(p.name)
            if e is None:
                if p.kind == "VAR_IN_OUT":
                    if fb:
                        # matiec accepts it: the instance keeps the variable of its last call
                        self.warn(c.pos, "W0012", f"portability: VAR_IN_OUT '{p.name}' of {pou.name} is "
                                  "not passed: the instance uses the variable of its previous "
                                  "call (none on the first call: the program crashes)")
                    else:
                        self.err(c.pos, "S0627", f"VAR_IN_OUT '{p.name}' of {pou.name} must be passed")
                continue
            try:
                if p.kind == "VAR_IN_OUT" and p.type.is_fb and isinstance(e, S.Name):
                    # an FB instance bound to an FB in-out (vendor dialects: CODESYS's rClient)
                    v = self.lookup(e)
                    e.var, e.ty, t = v, v.type, v.type
                elif p.kind == "VAR_IN_OUT":
                    t = self.lvalue(e, "pass as VAR_IN_OUT")
                    if not _is_variable(e):
                        self.fail(e.pos, "S0628", f"VAR_IN_OUT '{p.name}' needs a variable")
                    if not T.same_type(t, p.type) and not (
                            self.dialect.arrays_by_shape and t.is_array and T.same_type(t, p.type, False)):
                        self.fail(e.pos, "S0629", f"VAR_IN_OUT '{p.name}' is {p.type}, got {t}")
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
            self.fail(c.pos, "S0630", f"{n} takes {len(names)} arguments ({', '.join(names)}), got {len(c.args)}")
        if all(isinstance(a, S.ArgIn) for a in c.args):
            given = {a.name: a.value for a in c.args}
            if set(given) != set(names):
                self.fail(c.pos, "S0631", f"{n} takes the inputs {', '.join(names)}")
            args = [given[k] for k in names]
        elif any(isinstance(a, S.ArgIn) for a in c.args):
            self.fail(c.pos, "S0617", "mixing positional and named (:=) arguments is not allowed")
        else:
            args = [a.value for a in c.args]
        for k, a in zip(names, args):
            if k.startswith("IN"):
                t = self.expr(a, T.STRING)
                if not T.same_type(t, T.STRING):
                    self.fail(a.pos, "S0632", f"{n}: {k} is a STRING, not {t}")
            else:
                t = self.expr(a, None)
                if t.is_lit and t.kind != "real":
                    self.settle(a, T.INT)
                elif not (t.is_elem and t.is_int):
                    self.fail(a.pos, "S0633", f"{n}: {k} is an integer, not {t}")
        c.argv = args
        return _int_result(expected) if n == "FIND" else T.STRING

    def conversion(self, c, conv):
        src, dst = conv
        args = c.args
        if len(args) != 1 or not isinstance(args[0], S.ArgPos):
            self.fail(c.pos, "S0634", f"{c.name} takes one argument")
        a = args[0].value
        st = T.ELEMENTARY[src]
        t = self.expr(a, st)
        self.coerce(a, t, st, f"argument of {c.name}")
        c.kind = "conv"
        c.conv = (T.ELEMENTARY[src], T.ELEMENTARY[dst])
        return T.ELEMENTARY[dst]
