import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from kit_helpers import copy_example  # noqa: E402


@pytest.fixture
def example(tmp_path):
    """A copy of kit/example/ in tmp_path (the project the tests change)."""
    return copy_example(tmp_path / "project")
