"""C text of types, names and literals, and the small pieces the generator's parts share."""
import math

from .. import syntax as S

HEADER = "stc_rt.h"


def _c_elem(t):
    if t.is_enum:
        return "int"
    if t.is_elem:
        return t.ctype
    return t.name     # struct, FB, named array typedef


def cdecl(t, name):
    """C declaration of `name` with IEC type t."""
    if t.is_array and not t.name:
        dims = "".join(f"[{hi - lo + 1}]" for lo, hi in t.dims)
        return f"{_c_elem(t.elem)} {name}{dims}"
    return f"{_c_elem(t)} {name}"


def _own_copy(v):
    """An in-out (not of a function block type) that an instance keeps a copy of."""
    return not v.type.is_fb


def ptr_decl(t, name):
    if t.is_array and not t.name:
        return cdecl(t, f"(*{name})")
    return f"{_c_elem(t)} *{name}"


def _c_string(v):
    out = []
    for ch in v:
        o = ord(ch) & 0xFF
        if ch in '"\\?':
            out.append("\\" + ch)
        elif 32 <= o < 127:
            out.append(ch)
        else:
            out.append(f"\\{o:03o}")
    return '"' + "".join(out) + '"'


def lit(v, t):
    if t.is_enum:
        return str(v)
    if t.kind == "ptr":
        return "((void *)0)"    # (a POINTER's only literal value: its initial 0)
    if t.kind == "string":
        v = v or ""
        return f"((stc_string){{{len(v)}u, {_c_string(v)}}})" if v else "((stc_string){0u, {0}})"
    if t.kind == "real":
        v = float(v)
        if math.isinf(v) or math.isnan(v):
            v = 0.0
        s = repr(v)
        if "e" not in s and "." not in s:
            s += ".0"
        return s + ("f" if t.bits == 32 else "")
    if t.kind == "time":
        v = _wrap(int(v), 64, True)
        if v == -(1 << 63):
            return "(-INT64_C(9223372036854775807) - 1)"
        return f"INT64_C({v})" if v >= 0 else f"(-INT64_C({-v}))"
    if t.kind == "bool":
        return "1" if v else "0"
    v = int(v)
    signed = t.kind == "sint"
    v = _wrap(v, t.bits, signed)
    if t.bits == 64:
        if signed:
            if v == -(1 << 63):
                return "(-INT64_C(9223372036854775807) - 1)"
            return f"INT64_C({v})" if v >= 0 else f"(-INT64_C({-v}))"
        return f"UINT64_C({v})"
    if signed:
        if v == -(1 << 31):
            return "(-2147483647 - 1)"
        return str(v) if v >= 0 else f"({v})"
    return f"{v}u"


def _wrap(v, bits, signed):
    v &= (1 << bits) - 1
    if signed and v >= 1 << (bits - 1):
        v -= 1 << bits
    return v


def _wide(t):
    return "uint64_t" if t.bits == 64 else "uint32_t"


def _type_tag(t):
    """Type tag of a retained variable (part of the layout hash of a snapshot)."""
    if t.is_array:
        dims = ",".join(f"{lo}..{hi}" for lo, hi in t.dims)
        return f"ARRAY[{dims}] OF {_type_tag(t.elem)}"
    if t.is_enum:
        return f"ENUM:{t.name}"
    if t.is_struct:
        return f"STRUCT:{t.name}"
    if t.is_fb:
        return f"FB:{t.pou.name}"
    return t.name


def _body_eno(pou):
    """The FUNCTION's body sets ENO (it then reports it through a pointer argument)."""
    return pou.kind == "function" and "ENO" in getattr(pou, "implicit", {})


def _balanced(s):
    depth = 0
    for ch in s:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
            if depth < 0:
                return False
    return depth == 0


def _const(e):
    if isinstance(e, S.Paren):
        return _const(e.inner)
    if isinstance(e, S.IntLit):
        return e.value
    if isinstance(e, S.UnOp) and e.op == "-" and isinstance(e.operand, S.IntLit):
        return -e.operand.value
    return None
