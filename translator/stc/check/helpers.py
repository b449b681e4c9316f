"""The checker's small shared pieces: name rules and literal helpers."""
import re

from .. import syntax as S
from .. import types as T


_IDENT_RE = re.compile(r"^[A-Z_][A-Z0-9_]*$")
# macros of <stdint.h>/<string.h> that an upper-case IEC name would collide with in the C output
_C_MACROS = re.compile(r"^(U?INT(8|16|32|64|MAX|PTR)_(MIN|MAX|C)|U?INT_(LEAST|FAST)(8|16|32|64)_(MIN|MAX)"
                       r"|SIZE_MAX|PTRDIFF_(MIN|MAX)|SIG_ATOMIC_(MIN|MAX)|WCHAR_(MIN|MAX)|WINT_(MIN|MAX)"
                       r"|NULL|STC_[A-Z0-9_]*)$")



def _lit_fits(value, ty):
    r = ty.range()
    if r is None:
        return True
    return r[0] <= value <= r[1]



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


def _keywords():
    if not _KW:
        from .. import parser
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
