"""TIME under matiec: its standard library multiplies a TIME by an integer n as tv_sec * n
seconds plus (int)(tv_nsec * n) nanoseconds through a 32-bit int (lib/C/iec_std_lib.h,
__time_mul), so `T#1ms * 2148` comes out negative. The example programs build every TIME from
seconds and milliseconds (mipprograms.common: ms_to_time). These tests check

- every TIME product in plc/*.st and st_lib/*/*.st, for the whole range of its operand, stays
  inside that int (a model of matiec's arithmetic, so it runs without matiec);
- the generated expressions give the right TIME (3000 ms, 60 s, the WORD maximum) under stc;
- the chain with tTimeout 3000 ms and 60 s makes no spurious retransmission, under stc and,
  where iec2c is installed, under matiec (stock OpenPLC made 737 with the old expression).
"""
import re
from pathlib import Path

import pytest
from plcharness import Plc
from plcharness.build import matiec_available

from mipcosim import programs as L
from mipcosim.check import check
from mipcosim.sim import MS, SEC, LoggerLink, Setup

REPO = Path(__file__).resolve().parents[2]
from mipprograms.common import config, ms_to_time, s_to_time

INT_MAX = 2**31 - 1
WORD_MAX = 65535
UNITS_NS = {"ms": 10**6, "s": 10**9, "m": 60 * 10**9, "h": 3600 * 10**9, "d": 86400 * 10**9}
PAREN = r"\((?:[^()]|\([^()]*\))*\)"
OPERAND = rf"(?:{PAREN}|\w+{PAREN}|\w+)"
PRODUCT = re.compile(rf"(T#[\w.]+|\w+)\s*\*\s*({OPERAND})")


def literal_ns(lit):
    """T#1s500ms -> nanoseconds, or None when `lit` is not a TIME literal."""
    m = re.fullmatch(r"T#((?:\d+(?:ms|s|m|h|d))+)", lit, re.I)
    if not m:
        return None
    return sum(int(n) * UNITS_NS[u.lower()]
               for n, u in re.findall(r"(\d+)(ms|s|m|h|d)", m.group(1), re.I))


def bound(expr):
    """The largest value an integer operand of a TIME product takes (None: unknown)."""
    e = expr.strip()
    while e.startswith("(") and e.endswith(")") and re.fullmatch(PAREN, e):
        e = e[1:-1].strip()
    if re.fullmatch(r"\d+", e):
        return int(e)
    word = r"WORD_TO_(?:U?DINT|UINT)\(\w+\)"
    if re.fullmatch(word, e):
        return WORD_MAX
    m = re.fullmatch(rf"{word}\s+MOD\s+(\d+)", e)
    if m:
        return int(m.group(1)) - 1
    m = re.fullmatch(rf"{word}\s*/\s*(\d+)", e)
    if m:
        return WORD_MAX // int(m.group(1))
    return None


def matiec_product_problems(path, time_vars):
    """Products `TIME * n` in `path` that matiec's __time_mul may get wrong."""
    text = re.sub(r"\(\*.*?\*\)", lambda m: "\n" * m.group(0).count("\n"), Path(path).read_text(),
                  flags=re.S)
    problems = []
    for m in PRODUCT.finditer(text):
        left, right = m.group(1), m.group(2)
        ns = literal_ns(left)
        if ns is None and left.upper() not in time_vars:
            continue                       # not a TIME product
        line = text.count("\n", 0, m.start()) + 1
        n = bound(right)
        where = f"{Path(path).name}:{line}: {m.group(0)}"
        if n is None:
            problems.append(f"{where}: the multiplier has no known bound")
            continue
        nsec = ns % 10**9 if ns is not None else 10**9 - 1   # a TIME variable: any nsec part
        sec = ns // 10**9 if ns is not None else None
        if nsec * n > INT_MAX:
            problems.append(f"{where}: tv_nsec * n reaches {nsec * n} > 2**31 - 1")
        if sec is not None and sec * n > INT_MAX:
            problems.append(f"{where}: tv_sec * n overflows a 32-bit long")
    return problems


def time_variables(path):
    code = re.sub(r"\(\*.*?\*\)", " ", Path(path).read_text(), flags=re.S)
    return {n.upper() for n in re.findall(r"^\s*(\w+)\s*:\s*TIME\b", code, re.M)}


SOURCES = sorted((REPO / "plc").glob("*.st")) + sorted((REPO / "st_lib").glob("*/*.st"))


@pytest.mark.parametrize("path", SOURCES, ids=[p.name for p in SOURCES])
def test_time_products_stay_inside_matiecs_int(path):
    assert matiec_product_problems(path, time_variables(path)) == []


def test_the_model_refuses_the_old_expression(tmp_path):
    """The check above can fail: the expression the programs used before is refused."""
    bad = tmp_path / "old.st"
    bad.write_text("PROGRAM P\nVAR\n  t : TIME;\n  d : TIME;\nEND_VAR\n"
                   "t := T#1ms * WORD_TO_DINT(pTimeout);\nd := t * 3;\nt := T#1s * 65535;\n"
                   "END_PROGRAM\n")
    problems = matiec_product_problems(bad, time_variables(bad))
    assert len(problems) == 2, problems
    assert ":6: T#1ms * WORD_TO_DINT(pTimeout): tv_nsec * n reaches 65535000000" in problems[0]
    assert ":7: t * 3: tv_nsec * n reaches 2999999997" in problems[1]


PROBE = """
PROGRAM Probe
VAR
  pMs : WORD;
  pS : WORD;
  tMs : TIME;
  tS : TIME;
END_VAR
tMs := {ms};
tS := {s};
END_PROGRAM
""" + config("Probe", "p0")


def test_generated_time_expressions_give_the_time_under_stc(tmp_path):
    src = tmp_path / "probe.st"
    src.write_text(PROBE.format(ms=ms_to_time("pMs"), s=s_to_time("pS")))
    with Plc.build([src], workdir=tmp_path / "b", compiler="stc") as plc:
        for ms in (0, 1, 999, 1000, 2147, 2148, 3000, 60000, WORD_MAX):
            plc["Probe.pMs"] = ms
            plc["Probe.pS"] = ms
            plc.scan()
            # matiec converts the literal T#1ms through a long double to 999,999 ns (stc
            # reproduces it, translator/README.md): at most 1 ns short per millisecond of the
            # part below a second, never more, and the whole seconds exact
            got = plc["Probe.tMs"]
            assert ms * MS - (ms % 1000) <= got <= ms * MS, (ms, got)
            assert plc["Probe.tS"] == ms * SEC, ms
    # the programs use exactly these expressions for their millisecond parameters
    for name in ("outstation.st", "central.st", "outstation_bidi.st", "central_bidi.st"):
        text = (REPO / "plc" / name).read_text()
        for p in ("pTimeout", "pLogPeriod", "pCyclicWrite"):
            assert ms_to_time(p) in text, (name, p)
        assert f"tTransferTimeout := {s_to_time('pTransferTimeout')};" in text


COMPILERS = [pytest.param("stc"),
             pytest.param("matiec", marks=pytest.mark.skipif(
                 not matiec_available(),
                 reason="iec2c not on PATH (set PATH and MATIEC_LIB to run the chain on matiec)"))]


@pytest.mark.parametrize("compiler", COMPILERS)
@pytest.mark.parametrize("timeout_ms", [3000, 60000])
def test_chain_long_timeout_makes_no_spurious_retransmission(chain_workdir, compiler, timeout_ms):
    """No loss, transfers far shorter than tTimeout: a right tTimeout never fires. A wrong
    (negative) one fires at once and re-sends every record."""
    st = Setup(loss=0.0, seed=3, records=12, per_transfer=4, timeout_ms=timeout_ms,
               compiler=compiler)
    with LoggerLink(st, chain_workdir) as ch:
        assert ch.run_to_end(600 * SEC), f"not read out after {ch.now / SEC:.0f} s"
        reps = check(ch)
        retrans = ch.mw(("out", 1), L.peer_base(1) + L.S_RETRANS)
        dup = ch.mw(("cen", 0), L.peer_base(1) + L.R_DUP)
    assert [p for r in reps for p in r.problems] == []
    assert all(r.records == 12 and r.duplicated_records == 0 for r in reps)
    assert (retrans, dup) == (0, 0)
