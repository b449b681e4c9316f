"""The bench's own tools: the goodput model against the simulation kernel, and bad input handling."""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BUILD = REPO / "build" / "bench"
from mipbench import common, goodput, scan_cost, translator
from plcharness.procs import free_port


def test_model_at_no_loss_is_the_bound():
    assert goodput.goodput_model(0.0) == pytest.approx(common.PAYLOAD / 2)


def test_model_decreases_with_loss():
    g = [goodput.goodput_model(p / 10) for p in range(0, 9)]
    assert all(a > b for a, b in zip(g, g[1:]))


@pytest.mark.parametrize("p", [0.0, 0.3])
def test_model_matches_the_kernel(p, tmp_path):
    """Records of the example programs (st_lib via stc) through the simulation kernel at 9600
    bit/s: the measured payload per poll is within 10 % of the model (the model assumes the
    ends react between two polls, which 10 ms scans at 9600 bit/s do)."""
    polls, payload = goodput.goodput_cosim(p, 60, 7, tmp_path)
    assert payload / polls == pytest.approx(goodput.goodput_model(p), rel=0.10)


@pytest.mark.parametrize("prog,args", [("mb_client", ["127.0.0.1", "0", "1", "0", "125", "10"]),
                                       ("mb_client", ["127.0.0.1", "502", "1", "0", "126", "10"]),
                                       ("mb_bare_server", ["x"]),
                                       ("rss_run", [])])
def test_c_tools_bad_arguments(prog, args):
    p = subprocess.run([BUILD / prog, *args], capture_output=True, text=True, timeout=10)
    assert p.returncode == 2
    assert len(p.stderr.strip().splitlines()) == 1


def test_mb_client_connection_refused():
    port = free_port()      # nobody listens there
    p = subprocess.run([BUILD / "mb_client", "127.0.0.1", str(port), "1", "0", "125", "10"],
                       capture_output=True, text=True, timeout=10)
    assert p.returncode == 1 and "connect" in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_run_bench_unknown_figure():
    p = subprocess.run([sys.executable, "-m", "mipbench", "--only", "nonsense"],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == [p.stderr.strip()] and "unknown figure" in p.stderr
    assert "Traceback" not in p.stderr


def test_generated_st_has_5000_lines_and_translates(tmp_path):
    text = translator.gen_st(5000)
    n = text.count("\n")
    assert 5000 <= n <= 5500
    src = tmp_path / "gen.st"
    src.write_text(text)
    p = subprocess.run([REPO / ".venv" / "bin" / "stc", "-o", tmp_path / "out", src],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr


def test_scan_cost_without_matiec_says_why():
    """As in CI, where iec2c is absent: the stc figure is measured, the comparison skipped with
    the reason (BENCH_MATIEC=off stands in for a machine without matiec)."""
    import os
    env = dict(os.environ, BENCH_MATIEC="off")
    p = subprocess.run([sys.executable, "-m", "mipbench", "--quick", "--only",
                        "scan_cost"], capture_output=True, text=True, timeout=600, env=env)
    assert p.returncode == 0, p.stdout + p.stderr
    l = next(l for l in p.stdout.splitlines() if l.startswith("scan_cost:"))
    assert l.endswith("SKIPPED") and "matiec figure skipped: BENCH_MATIEC=off" in l, l
    import re
    assert int(re.search(r"stc (\d+) instructions", l).group(1)) > 0, l


def _needs_iec2c():
    from plcharness.build import matiec_available
    return pytest.mark.skipif(not matiec_available(),
                              reason="iec2c not on PATH (set PATH and MATIEC_LIB to run the matiec tests)")


@_needs_iec2c()
def test_scan_cost_against_matiec_counts_both_fb_bodies():
    """With iec2c on PATH the line compares with matiec: gcc splits matiec's FB bodies, and
    the callers call the clone (MIP_SENDER_body__.part.0), which a count by name alone
    missed (0 instructions: a ZeroDivisionError)."""
    p = subprocess.run([sys.executable, "-m", "mipbench", "--quick", "--only",
                        "scan_cost"], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stdout + p.stderr
    l = next(l for l in p.stdout.splitlines() if l.startswith("scan_cost:"))
    import re
    m = re.search(r"([\d.]+) of matiec \(stc (\d+), matiec (\d+) instructions.*FB bodies alone "
                  r"stc (\d+), matiec (\d+): ([\d.]+); target <= 0\.50\) (OK|MISSED)$", l)
    assert m, l
    ratio, stc, mat, stc_fb, mat_fb, fb_ratio, status = m.groups()
    assert 0 < int(stc_fb) < int(stc) and 0 < int(mat_fb) < int(mat), l
    assert float(ratio) == pytest.approx(int(stc) / int(mat), abs=0.001)
    assert status == ("OK" if float(ratio) <= 0.5 else "MISSED")


def test_inclusive_cost_takes_the_calls_into_gcc_clones_once():
    """Calls into a body or its clones from outside count with their inclusive cost; a call
    from the body into its own clone is inside it and is not counted twice."""
    out = "\n".join([
        "positions: line", "events: Ir",
        "fn=BENCHPAIR_body__", "10 5",
        "cfn=MIP_SENDER_body__.part.0", "calls=3 1", "11 300",
        "cfn=MIP_SENDER_body__", "calls=1 1", "12 120",
        "cfn=MIP_SENDERX_body__", "calls=1 1", "13 7",
        "fn=MIP_SENDER_body__", "1 20",
        "cfn=MIP_SENDER_body__.part.0", "calls=1 1", "2 100",
        "fn=MIP_LINK_body__",
        "cfn=MIP_RECEIVER_body__.constprop.0", "calls=2 1", "3 50",
    ])
    assert scan_cost.inclusive_cost(out, scan_cost.FB_BODIES) == 470
