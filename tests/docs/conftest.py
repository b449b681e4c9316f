"""tests/docs: the docs' tools build their PLCs in a directory of the test process, not in the
shared build/docs/ (two pytest-xdist workers running gen_traces and mipsim at once would
remove each other's builds)."""
import pytest

from docs_helpers import tool


@pytest.fixture(scope="session", autouse=True)
def docs_workdir(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MIP_DOCS_WORKDIR", str(tmp_path_factory.mktemp("docs-work")))
        yield


@pytest.fixture(scope="session")
def diagrams(tmp_path_factory):
    """The sequence diagrams as the code draws them now, from the checked-in traces (docs/img/
    may wait for `make docs-diagrams`): one `mkdiagrams` run for test_docs_diagrams and
    test_docs_seqdiag_marks."""
    out = tmp_path_factory.mktemp("seq")
    r = tool("mkdiagrams", "--outdir", out)
    assert r.returncode == 0, r.stderr
    return out
