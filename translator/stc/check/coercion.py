"""Implicit conversions (IEC strict typing and matiec's leniencies), settling literals, constant values."""
from .. import syntax as S
from .. import types as T
from .helpers import _conv_hint, _lit_fits


class CoercionChecks:
    """A part of Checker (check/__init__.py): its methods call the other parts' through self."""

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
                        self.fail(e.pos, "S0501", f"value {v} is out of range of {to_t}")
                    self.settle(e, to_t)
                    return
            elif from_t.kind == "real":
                if to_t.is_elem and to_t.kind == "real":
                    self.settle(e, to_t)
                    return
            if soft:
                return
            if from_t.kind == "int" and to_t.is_elem and to_t.kind == "real":
                self.fail(e.pos, "S0502", f"{what}: an integer literal cannot be {to_t} (matiec rejects it): "
                          "write a REAL literal like 1.0")
            self.fail(e.pos, "S0503", f"{what}: {from_t} cannot be {to_t}")
        if soft:
            return
        if T.same_type(from_t, to_t):
            return
        if self.dialect.arrays_by_shape and from_t.is_array and to_t.is_array \
                and T.same_type(from_t, to_t, False):
            return    # the vendor dialects assign arrays of the same bounds and element type
        if from_t.is_array and to_t.is_array and self.dialect.arrays_named_by_shape:
            self.fail(e.pos, "S0504", f"{what}: {from_t} cannot be {to_t}: SCL assigns and passes arrays "
                      "only between the same bounds and element type")
        if from_t.is_array and to_t.is_array:
            self.fail(e.pos, "S0505", f"{what}: arrays can only be assigned or passed between variables of "
                      "the same named array TYPE (matiec rejects anonymous ARRAY[..] types here): "
                      "declare a TYPE and use it on both sides")
        self.fail(e.pos, "S0506", f"{what}: type {from_t} cannot be assigned to {to_t} without explicit "
                  f"conversion (IEC strict typing): use {_conv_hint(from_t, to_t)}")

    def _strict_bit_literal(self, e, to_t, what):
        """--strict-iec: an untyped decimal integer literal stored in an ANY_BIT variable (BYTE,
        WORD, DWORD, LWORD). matiec, CODESYS and TwinCAT accept it; a strict IEC 61131-3
        edition-2 checker does not (a decimal literal is ANY_INT there). Typed (WORD#0) and
        based (16#0) literals are bit strings."""
        if (isinstance(e, S.IntLit) and not e.based and to_t.is_elem and to_t.kind == "bit"):
            self.warn(e.pos, "W0008", f"strict IEC: {what}: untyped integer literal {e.text} stored in "
                             f"{to_t} (a strict edition-2 checker rejects it): write "
                             f"{to_t}#{e.text} or a based literal like 16#{e.value:X}")

    def need_settled(self, e, t):
        if e.ty is None or e.ty.is_lit:
            if e.ty is not None and e.ty.kind == "int" and t.is_elem and t.kind == "real":
                self.fail(e.pos, "S0507", f"an integer literal cannot be used as {t} (matiec rejects it): "
                          "write a REAL literal like 1.0")
            self.fail(e.pos, "S0508", f"{e.ty or 'this value'} cannot be used as {t}")

    def range_check(self, e, t):
        if t.is_elem and (t.is_int or t.kind == "bit"):
            v = self.const_value(e)
            if v is not None and not _lit_fits(v, t):
                self.fail(e.pos, "S0501", f"value {v} is out of range of {t}")

    def settle(self, e, t):
        """Give untyped literal expression e the concrete type t (recursively)."""
        if e.ty is not None and not e.ty.is_lit:
            return
        e.ty = t
        if isinstance(e, S.Paren):
            self.settle(e.inner, t)
        elif isinstance(e, S.UnOp):
            if e.op == "-" and not (t.is_elem and t.kind in ("sint", "real", "time")):
                self.fail(e.pos, "S0509", f"unary minus on a value of type {t}")
            self.settle(e.operand, t)
        elif isinstance(e, S.BinOp):
            if e.op in self._ARITH and not (t.is_elem and t.is_num):
                self.fail(e.pos, "S0510", f"arithmetic '{e.op}' on literals used as {t} is not allowed: "
                          "compute it in an integer type")
            if e.op == "MOD" and not t.is_int:
                self.fail(e.pos, "S0452", f"MOD needs an integer type, not {t}")
            if e.op in self._LOGIC and not (t.is_elem and t.is_anybit):
                self.fail(e.pos, "S0511", f"{e.op} needs BOOL or a bit string type, not {t}")
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
