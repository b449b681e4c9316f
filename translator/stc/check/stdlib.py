"""The IEC standard functions stc supports, with matiec's typing of each."""
from .. import syntax as S
from .. import types as T
from .helpers import _int_result


class StdlibChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

    def std_func(self, c, expected):
        n = c.name
        c.kind = "std"
        args = []
        for a in c.args:
            if not isinstance(a, S.ArgPos):
                if isinstance(a, S.ArgIn):
                    args.append(a.value)
                    continue
                self.fail(a.pos, "S0701", f"{n} has no outputs")
            args.append(a.value)
        c.argv = args

        def need(k):
            if len(args) != k:
                self.fail(c.pos, "S0702", f"{n} takes {k} arguments, got {len(args)}")

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
                    self.fail(x.pos, "S0703", f"{n}: arguments must all have the same type ({t0}), got {t}; "
                              "convert explicitly")
            return t0

        if n in ("SHL", "SHR", "ROL", "ROR"):
            need(2)
            t = self.expr(args[0], expected)
            if t.is_lit:
                self.fail(args[0].pos, "S0704", f"{n} of an untyped literal: write a typed literal like WORD#16#FF")
            if not (t.is_elem and t.is_anybit):
                self.fail(args[0].pos, "S0705", f"{n} needs BOOL, BYTE, WORD, DWORD or LWORD, not {t}")
            nt = self.expr(args[1], None)
            if nt.is_lit:
                self.settle(args[1], T.DINT)
            elif not (nt.is_elem and nt.is_int):
                self.fail(args[1].pos, "S0706", f"{n}: shift count must be an integer, not {nt}")
            if n in ("SHL", "SHR") and t.bits > 1:
                k = self.const_value(args[1])
                cw = 64 if t.bits == 64 else 32
                if k is None:
                    self.warn(args[1].pos, "W0013", f"portability: {n} by a variable count differs between "
                              f"matiec and IEC when the count is >= {cw} (matiec shifts in C: "
                              f"x86 takes the count modulo {cw}); limit the count first")
                elif not 0 <= k < cw:
                    self.warn(args[1].pos, "W0014", f"portability: {n} of {t} by {k} differs between "
                              "matiec and IEC (IEC shifts everything out)")
            return t
        if n in ("ABS",):
            need(1)
            t = same(args, expected)
            if not (t.is_elem and t.is_num):
                self.fail(c.pos, "S0707", f"ABS needs a numeric type, not {t}")
            return t
        if n == "LEN":
            need(1)
            t = self.expr(args[0], T.STRING)
            if not T.same_type(t, T.STRING):
                self.fail(args[0].pos, "S0708", f"LEN needs a STRING, not {t}")
            return _int_result(expected)
        if n in T.STR_FUNCS:
            self.note(c.pos, "string-function", f"{n}: matiec's library has its own results "
                      "at the edges (FIND, REPLACE, positions 0)")
            return self.str_func(c, n, expected)
        if n == "CONCAT":
            if len(args) < 2:
                self.fail(c.pos, "S0709", "CONCAT takes at least 2 arguments")
            for a in args:
                t = self.expr(a, T.STRING)
                if not T.same_type(t, T.STRING):
                    self.fail(a.pos, "S0710", f"CONCAT needs STRINGs, not {t}")
            return T.STRING
        if n in ("SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN"):
            need(1)
            t = same(args, expected)
            if not (t.is_elem and t.kind == "real"):
                if t.is_elem and t.is_int:
                    self.fail(args[0].pos, "S0711", f"{n} needs REAL or LREAL, not {t} (matiec rejects "
                              f"it): convert first, e.g. {t.name}_TO_REAL(x)")
                self.fail(args[0].pos, "S0712", f"{n} needs REAL or LREAL, not {t}")
            c.kind = "math"
            return t
        if n == "TRUNC":
            need(1)
            t = self.expr(args[0], None)
            if t.is_lit and t.kind == "real":
                self.settle(args[0], T.ELEMENTARY["LREAL"])
                t = args[0].ty
            if not (t.is_elem and t.kind == "real"):
                self.fail(args[0].pos, "S0713", f"TRUNC needs REAL or LREAL, not {t}")
            if expected is None or not (expected.is_elem and expected.is_int):
                self.fail(c.pos, "S0714", "TRUNC: the result type must come from the context (assign it to "
                          "an integer variable) or use REAL_TO_DINT")
            c.kind = "trunc"
            return expected
        if n in ("MOVE",):
            need(1)
            t = same(args, expected)
            if t.is_array:
                self.fail(c.pos, "S0715", "MOVE of an ARRAY is not supported: assign the array variable")
            return t
        if n in ("MIN", "MAX", "LIMIT"):
            if n == "LIMIT":
                need(3)
            elif len(args) < 2:
                self.fail(c.pos, "S0716", f"{n} takes at least 2 arguments")
            t = same(args, expected)
            if not t.is_elem or t.kind == "string":
                self.fail(c.pos, "S0717", f"{n} needs a number, bit string or TIME, not {t}")
            return t
        if n == "SEL":
            need(3)
            self.cond(args[0], "SEL selector")
            t = same(args[1:], expected)
            if t.is_fb or t.is_array:
                self.fail(c.pos, "S0718", f"SEL of {t} is not supported")
            return t
        if n == "MUX":
            if len(args) < 2:
                self.fail(c.pos, "S0719", "MUX takes a selector and at least one input")
            kt = self.expr(args[0], None)
            if kt.is_lit:
                self.settle(args[0], T.DINT)
            elif not (kt.is_elem and kt.is_int):
                self.fail(args[0].pos, "S0720", f"MUX selector must be an integer, not {kt}")
            t = same(args[1:], expected)
            if t.is_fb or t.is_array:
                self.fail(c.pos, "S0721", f"MUX of {t} is not supported")
            k = self.const_value(args[0])
            if k is not None and not 0 <= k < len(args) - 1:
                self.warn(args[0].pos, "W0015", f"portability: MUX selector {k} is out of range 0.."
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
                self.fail(c.pos, "S0722", f"EXPT needs REAL or LREAL, not {t}")
            et = self.expr(args[1], None)
            if et.is_lit:
                self.settle(args[1], t if et.kind == "real" else T.DINT)
            elif not (et.is_elem and et.is_num):
                self.fail(args[1].pos, "S0723", f"EXPT: the exponent must be a number, not {et}")
            c.kind = "math"
            return t
        self.fail(c.pos, "S0724", f"standard function {n} is not supported by stc")
