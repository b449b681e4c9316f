import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "cosim"))   # mipcosim, also before `make venv` installed it


@pytest.fixture(scope="session")
def chain_workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("chain")
