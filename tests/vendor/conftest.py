from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

if not (REPO / "build" / "cosim" / "libmipcosim.so").is_file():
    pytest.fail("build/cosim/libmipcosim.so not built: run make first", pytrace=False)


@pytest.fixture(scope="session")
def vendor_workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("vendor")
