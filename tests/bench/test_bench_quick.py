"""`BENCH_QUICK=1 make bench` runs and prints the machine and every figure line (issue 8).

Benchmarks are not tests: nothing here checks a figure against its target, only that each
figure was measured (or says why it was skipped) and that the line has the agreed shape."""
import functools
import os
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

FIGURES = ["goodput_0pct", "goodput_10pct", "goodput_30pct", "scan_cost",
           "emu_throughput_vs_pymodbus", "emu_throughput_vs_bare", "cosim_speed", "cosim_scale",
           "translator_speed", "translator_speed_inprocess", "peak_rss_runtime_1st", "peak_rss_runtime_64st", "peak_rss_emulator_1st",
           "peak_rss_emulator_64st", "readout_realistic", "record_reaction", "kit_scenario",
           "goodput_rtu", "fc23_gain", "chain_goodput", "chain_goodput_push", "chain_latency_0pct",
           "chain_latency_30pct", "chain_ack_after_handover"]
STATUS = r"(OK|MISSED|SKIPPED|PENDING|INFO)"


@pytest.fixture(scope="module")
def bench_output():
    return _bench_output()


# once per process: under pytest-xdist a worker may run another module's tests between two of
# this module's, which ends a module fixture; the bench must not run twice for that
@functools.lru_cache(maxsize=None)
def _bench_output():
    env = dict(os.environ, BENCH_QUICK="1")
    p = subprocess.run(["make", "-s", "--no-print-directory", "bench"], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, f"make bench failed:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    return p.stdout


def test_machine_lines(bench_output):
    m = [l for l in bench_output.splitlines() if l.startswith("machine:")]
    text = "\n".join(m)
    for key in ("cpu=", "cores=", "kernel=", "cc=", "python=", "valgrind=", "libmodbus=", "iec2c="):
        assert key in text, f"{key} missing from the machine lines:\n{text}"
    assert "quick run" in bench_output


@pytest.mark.parametrize("name", FIGURES)
def test_figure_line(bench_output, name):
    lines = [l for l in bench_output.splitlines() if l.startswith(name + ":")]
    assert len(lines) == 1, f"expected one line for {name}, got {lines}\n{bench_output}"
    l = lines[0]
    assert re.search(STATUS + r"$", l), f"no status at the end: {l}"
    assert "ERROR" not in l.split()[-1]
    if l.endswith(("OK", "MISSED")):
        assert "target" in l, f"a figure with a target names it: {l}"


def test_scan_cost_matiec_skip_says_why(bench_output):
    l = next(l for l in bench_output.splitlines() if l.startswith("scan_cost:"))
    if l.endswith("SKIPPED"):
        assert "matiec figure skipped" in l and "iec2c" in l and re.search(r"stc \d+", l), l
    else:
        assert re.search(r"stc \d+, matiec \d+", l), l


def test_goodput_says_how_it_was_measured(bench_output):
    for l in bench_output.splitlines():
        if l.startswith("goodput_"):
            assert "cosim:" in l, l


def test_no_server_left_behind(bench_output):
    """Every server the bench started is gone (names of its processes in /proc)."""
    mine = {"mb_bare_server", "rss_run"}
    left = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                comm = (d / "comm").read_text().strip()
                cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if comm in mine or "mipbench.pymodbus_server" in cmd:
                left.append((d.name, cmd))
    assert not left, f"processes left running: {left}"
