"""matiec's TIME arithmetic, in the one place the translator keeps it.

matiec's library scales a TIME's seconds in double and its nanoseconds through a 32-bit int, and
builds a duration literal from the numbers as written (so T#1ms * 2148 is -2.147483648 s, and
T#1ms is 999999 ns). The C runtime header stc_rt.h does the same at run time (stc_mt_mul,
stc_mt_div, stc_mt_lit); the checker folds constants with time_mul / time_div, and the code
generator passes literal_parts to stc_mt_lit. tests/translator/test_stc_matiec_time_arith.py
holds the Python here and the C header to the same values."""
import re


def _c_div(a, b):
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q


def _c_i32(d):
    return int(d) if -2**31 <= d < 2**31 else -2**31


def _c_i64(d):
    return int(d) if -9.2e18 <= d < 9.2e18 else -2**63


def time_mul(ns, k):
    """matiec's TIME * k in nanoseconds, as stc_rt.h's stc_mt_mul computes it."""
    sec, nsec = _c_div(ns, 10**9), ns - _c_div(ns, 10**9) * 10**9
    s_f = float(sec) * k
    s = _c_i64(s_f)
    n = _c_i32(float(nsec) * k)
    q = _c_div(n, 10**9)
    return (s + q) * 10**9 + _c_i64(float(n - q * 10**9) + (s_f - s) * 1e9)


def time_div(ns, k):
    """matiec's TIME / k in nanoseconds, as stc_rt.h's stc_mt_div computes it (k != 0)."""
    sec, nsec = _c_div(ns, 10**9), ns - _c_div(ns, 10**9) * 10**9
    s_f = float(sec) / k
    s = _c_i64(s_f)
    return s * 10**9 + _c_i64(float(nsec) / k + (s_f - s) * 1e9)


_MT_PART = re.compile(r"([0-9]+(?:\.[0-9]+)?)(ms|d|h|m|s)", re.I)


def literal_parts(text):
    """matiec's arguments (sign, ms, s, m, h, d) for a duration literal such as T#1h2m3s4ms,
    each number as written; None for what matiec's literal does not have (us, ns, a unit
    twice)."""
    body = (text or "").split("#", 1)[-1].replace("_", "")
    sign = "1"
    if body[:1] in "+-" and body:
        sign = "-1" if body[0] == "-" else "1"
        body = body[1:]
    parts, pos = {}, 0
    while pos < len(body):
        m = _MT_PART.match(body, pos)
        if not m or m.group(2).lower() in parts:
            return None
        parts[m.group(2).lower()] = m.group(1)
        pos = m.end()
    if not parts:
        return None
    return [sign] + [(v if "." in v else f"{int(v)}.0") for v in
                     (parts.get(u, "0") for u in ("ms", "s", "m", "h", "d"))]
