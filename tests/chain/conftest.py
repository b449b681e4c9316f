from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def chain_workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("chain")
