"""The interop matrix of issue 11, cell by cell: our blocks (plc/ programs, soft-PLCs of the
co-simulation kernel) against the note-only peer (peers/mippeer, strict or lenient, a participant
of the same kernel), in virtual time. Each cell must end "complete" (every record exactly once, in
order, register for register, and the sender saw its last record acknowledged) or with an error
of our blocks within the bound; silent loss or duplication and hangs fail.

The whole matrix (88 cells) takes a few seconds; the session writes its results to
build/interop/pytest-matrix.json (`python -m mipinterop --write-docs` makes the table of it).
Also here: the same seed gives the same cell (result and emulator trace, byte for byte), each
side of a restart goes on in virtual time while the other is down, and one cell of the
real-time run (--realtime) still works.
"""
import time
from dataclasses import asdict

import pytest
from mipcosim.trace import read_trace

from mipcosim.kernel import SEC
from mipinterop import kernel
from mipinterop.matrix import (EMU, Cell, Config, MatrixError, all_cells, build_programs,
                               run_cell)


@pytest.fixture(scope="module")
def progs(tmp_path_factory):
    return kernel.build_programs(tmp_path_factory.mktemp("interop-build"))


@pytest.mark.parametrize("cell", all_cells(), ids=lambda c: c.key.replace("/", "-"))
def test_interop_cell(cell, progs, tmp_path, matrix_results):
    seed = 1 + [c.key for c in all_cells()].index(cell.key)
    t = time.monotonic()
    try:
        r = run_cell(cell, Config(), progs, tmp_path, seed=seed)
    except MatrixError as e:
        pytest.fail(f"{cell.key}: the cell could not run: {e}", pytrace=False)
    matrix_results["results"].append(asdict(r))
    matrix_results["seconds"] += time.monotonic() - t
    assert r.passed, f"{cell.key}: {r.text} (errors seen: {r.errors}; streams: {r.streams})"
    assert r.outcome in ("complete", "error")
    if r.outcome == "error":
        assert r.error_after_s <= Config().bound_s


@pytest.mark.parametrize("key", ["receiver/strict/loss30/bi/static",
                                 "sender/lenient/restart-peer/bi/dynamic"])
def test_same_seed_same_cell(key, progs, tmp_path):
    """Deterministic by seed: the result (but the wall time) and the emulator's trace, byte for
    byte; another seed loses other telegrams (with loss; without, the seed changes nothing)."""
    cell = Cell.parse(key)
    runs = []
    for i, seed in enumerate((5, 5, 6)):
        r = run_cell(cell, Config(), progs, tmp_path / str(i), seed=seed)
        runs.append((asdict(r) | {"seconds": None},
                     (tmp_path / str(i) / "trace.jsonl").read_bytes()))
    assert runs[0][0]["passed"]
    assert runs[0] == runs[1]
    assert (runs[0][1] != runs[2][1]) == (cell.fault == "loss30")


def _requests(trace, ep):
    return [e["t"] for e in read_trace(trace)
            if e.get("ev") == "modbus" and e.get("ep") == ep]


@pytest.mark.parametrize("fault", ["restart-ours", "restart-peer"])
def test_the_other_side_goes_on_while_one_is_down(fault, progs, tmp_path):
    """A restart in virtual time: while our soft-PLC (restart-ours) or the peer (restart-peer)
    is off for Config.down_s, only the other side talks to its modem; then both again."""
    run = kernel.KernelRun(Cell.parse(f"sender/lenient/{fault}/uni/dynamic"), Config(), progs,
                           tmp_path, seed=3)
    r = run.run()
    assert r.outcome == "complete", r
    [(t_off, t_on, who)] = run.faults
    assert who == fault.split("-")[1]
    assert t_on - t_off >= Config().down_s * SEC
    trace = tmp_path / "trace.jsonl"
    ours, peer = _requests(trace, "trm"), _requests(trace, "mdp")
    down, up = (ours, peer) if who == "ours" else (peer, ours)
    assert not [t for t in down if t_off < t < t_on]
    assert len([t for t in up if t_off < t < t_on]) >= Config().down_s / 0.02
    assert [t for t in down if t >= t_on]


def test_one_cell_in_real_time(tmp_path):
    """--realtime: the soft-PLC and mip-peer processes over mip-emulator, the same judge."""
    if not EMU.is_file():
        pytest.fail(f"{EMU} not built: run make first", pytrace=False)
    progs = build_programs(tmp_path / "build")
    r = run_cell(Cell.parse("sender/strict/none/uni/dynamic"), Config(), progs, tmp_path / "cell",
                 realtime=True)
    assert r.outcome == "complete" and r.virtual_s is None, r
