"""The interop matrix of issue 11, cell by cell: our blocks in the soft-PLC (plc/ programs,
real time) against the note-only peer (peers/, `mip-peer --strict|--lenient`) over
build/emulator/mip-emulator. Each cell must end "complete" (every record exactly once, in
order, register for register, and the sender saw its last record acknowledged) or with an
error of our blocks within the bound; silent loss or duplication and hangs fail.

The whole matrix (64 cells) takes about 3 minutes on the fast radio; the session writes its
results to build/interop/pytest-matrix.json (the table's source, see tests/interop/README.md).
"""
import time
from dataclasses import asdict

import pytest

from mipinterop.matrix import EMU, Config, MatrixError, all_cells, build_programs, run_cell

if not EMU.is_file():
    pytest.fail(f"{EMU} not built: run make first (the matrix cannot run without it)",
                pytrace=False)


@pytest.fixture(scope="module")
def progs(tmp_path_factory):
    return build_programs(tmp_path_factory.mktemp("interop-build"))


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
