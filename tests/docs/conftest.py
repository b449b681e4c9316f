"""tests/docs: the docs' tools build their PLCs in a directory of the test process, not in the
shared build/docs/ (two pytest-xdist workers running gen_traces and mipsim at once would
remove each other's builds)."""
import pytest


@pytest.fixture(scope="session", autouse=True)
def docs_workdir(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MIP_DOCS_WORKDIR", str(tmp_path_factory.mktemp("docs-work")))
        yield
