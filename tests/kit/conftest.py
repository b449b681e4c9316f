import pytest

from kit_helpers import copy_example


@pytest.fixture
def example(tmp_path):
    """A copy of kit/example/ in tmp_path (the project the tests change)."""
    return copy_example(tmp_path / "project")
