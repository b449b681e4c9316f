"""The three tiers (tests/conftest.py, Makefile): make test leaves the slow tests out, make check
the large ones, and make check-large runs exactly those, beside the model's largest proofs. CI
runs make check and make check-large, so together they must run every test."""
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _make_n(*targets):
    r = subprocess.run(["make", "-n", "--no-print-directory", *targets], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_check_leaves_the_large_tier_to_check_large():
    assert 'PYTEST_MARK="not large"' in _make_n("check")
    large = _make_n("check-large")
    assert "suite/py-tests-large" in large and "suite/model-large" in large, large
    assert " -m large " in _make_n("py-tests-large")
    assert "--tier large" in _make_n("model-large")


def _collected(*mark):
    r = subprocess.run([str(ROOT / ".venv/bin/python"), "-m", "pytest", "-q", "-p",
                        "no:cacheprovider", "--collect-only", *mark, "tests"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return {line for line in r.stdout.splitlines() if "::" in line}


@pytest.mark.slow   # two collections of the whole suite (about 10 s of CPU each)
def test_the_large_tier_is_what_large_tier_names_and_never_in_make_test(large_tier):
    large = _collected("-m", "large")
    quick = _collected("-m", "not slow")
    assert large and not large & quick
    assert all(t.startswith(tuple(large_tier)) for t in large)
    assert all(any(t.startswith(e) for t in large) for e in large_tier)
