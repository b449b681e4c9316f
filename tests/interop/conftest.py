import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

RESULTS = REPO / "build" / "interop" / "pytest-matrix.json"


@pytest.fixture(scope="session")
def matrix_results():
    """Every cell the session ran; written as the matrix's JSON results at the end, so that
    `python -m mipinterop --write-docs build/interop/pytest-matrix.json` makes the table
    from this very run."""
    collected = {"results": [], "seconds": 0.0, "clock": "virtual"}
    yield collected
    if collected["results"]:
        from mipinterop.matrix import Config, all_cells
        from dataclasses import asdict
        cfg = Config()
        order = {c.key: i for i, c in enumerate(all_cells())}
        collected["results"].sort(key=lambda r: order[r["cell"]])
        collected["config"] = asdict(cfg) | {"bound_s": cfg.bound_s}
        collected["seconds"] = round(collected["seconds"], 1)
        collected["virtual_seconds"] = round(sum(r["virtual_s"] or 0
                                                 for r in collected["results"]), 1)
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        RESULTS.write_text(json.dumps(collected, indent=1) + "\n")
