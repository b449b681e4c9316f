"""matiec's TIME * k and TIME / k are computed twice: by the checker when it folds a constant
(stc/matiec_time.py) and by the C runtime at run time (stc_rt.h's stc_mt_mul / stc_mt_div).
The two must give the same nanoseconds, including where matiec's 32-bit nanosecond step wraps
(T#1ms * 2148 is -2.147483648 s)."""
import subprocess
from pathlib import Path

import pytest

import stc
from stc import matiec_time

HEADER_DIR = Path(stc.__file__).resolve().parent
PROGRAM = r"""
#include "stc_rt.h"
int main(void)
{
    long long ns; double k; char op;
    while (scanf(" %c %lld %lf", &op, &ns, &k) == 3) {
        stc_time t = stc_mt_of(ns);
        stc_time r = op == '*' ? stc_mt_mul(t, k) : stc_mt_div(t, k);
        printf("%ld %ld\n", r.tv_sec, r.tv_nsec);     /* a pair: its total may pass int64 */
    }
    return 0;
}
"""
NS = [0, 1, 999_999, 1_000_000, 1_500_000_000, -1_500_000_000, 2_000_000_000, 86_400_000_000_000,
      -999_999, 123_456_789_012]
K = [1, 2, 3, -1, -7, 0.5, 2.5, 2148, 1000, 1e6, -0.25]


@pytest.fixture(scope="module")
def runtime_arith(tmp_path_factory):
    d = tmp_path_factory.mktemp("mt")
    (d / "mt.c").write_text(PROGRAM)
    subprocess.run(["cc", "-std=gnu11", "-O1", f"-I{HEADER_DIR}", str(d / "mt.c"), "-o",
                    str(d / "mt"), "-lm"], check=True, capture_output=True, text=True)

    def run(cases):
        text = "".join(f"{op} {ns} {k!r}\n" for op, ns, k in cases)
        out = subprocess.run([str(d / "mt")], input=text, capture_output=True, text=True,
                             check=True).stdout
        return [int(s) * 10**9 + int(n) for s, n in (line.split() for line in out.splitlines())]
    return run


def test_the_checker_folds_time_arithmetic_as_the_runtime_computes_it(runtime_arith):
    cases = [(op, ns, k) for ns in NS for k in K for op in "*/"]
    c = runtime_arith(cases)
    py = [matiec_time.time_mul(ns, k) if op == "*" else matiec_time.time_div(ns, k)
          for op, ns, k in cases]
    differ = [(case, a, b) for case, a, b in zip(cases, py, c) if a != b]
    assert not differ, f"{len(differ)} of {len(cases)} differ, e.g. (op, ns, k), python, C: {differ[:5]}"


def test_the_wrap_the_module_describes():
    assert matiec_time.time_mul(1_000_000, 2148) == -2_147_483_648


def test_literal_parts_as_matiec_reads_a_duration():
    assert matiec_time.literal_parts("T#1h2m3s4ms") == ["1", "4.0", "3.0", "2.0", "1.0", "0.0"]
    assert matiec_time.literal_parts("T#-1.5s") == ["-1", "0.0", "1.5", "0.0", "0.0", "0.0"]
    assert matiec_time.literal_parts("T#5us") is None
