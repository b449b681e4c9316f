"""Conformance corpus: accept/*.st must translate, compile with -Werror and produce the
(* EXPECT path = value *) values after (* SCANS n *) scans; reject/*.st must fail with the
(* ERROR line:col: message *) diagnostics."""
import glob
import os

import pytest

import stc_harness as H

ACCEPT = sorted(glob.glob(os.path.join(H.HERE, "accept", "*.st")))
REJECT = sorted(glob.glob(os.path.join(H.HERE, "reject", "*.st")))


def _id(p):
    return os.path.splitext(os.path.basename(p))[0]


@pytest.mark.parametrize("semantics", ["matiec", "openplc", "iec"])
@pytest.mark.parametrize("path", ACCEPT, ids=_id)
def test_accept(path, semantics, tmp_path):
    with open(path) as f:
        text = f.read()
    scans, expects, sets = H.expectations(text, semantics)
    assert expects, f"{path}: no (* EXPECT ... *) lines"
    exe = H.build([path], str(tmp_path), semantics=semantics)
    values = H.run(exe, scans, sets)
    for sym, want in expects:
        got = H.lookup(values, sym)
        assert got == want.replace(" ", ""), f"{sym}: got {got}, want {want}"


@pytest.mark.parametrize("path", REJECT, ids=_id)
def test_reject(path, tmp_path):
    with open(path) as f:
        text = f.read()
    want = H.expected_errors(text)
    assert want, f"{path}: no (* ERROR line:col: message *) lines"
    r = H.translate(["-o", str(tmp_path / "out"), path])
    assert r.returncode == 1, f"accepted (rc={r.returncode}): {r.stderr}"
    assert "Traceback" not in r.stderr and "internal" not in r.stderr, r.stderr
    lines = r.stderr.splitlines()
    for line, col, msg in want:
        prefix = f"{path}:{line}:{col}: error: "
        hits = [x for x in lines if x.startswith(prefix)]
        assert hits, f"no error at {line}:{col}; got:\n{r.stderr}"
        assert any(msg.lower() in x.lower() for x in hits), \
            f"error at {line}:{col} does not mention {msg!r}:\n{r.stderr}"


def test_corpus_sizes():
    # the issue asks for substantial corpora; keep them from shrinking silently
    assert len(ACCEPT) >= 60, len(ACCEPT)
    assert len(REJECT) >= 60, len(REJECT)
