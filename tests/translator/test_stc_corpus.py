"""Conformance corpus: accept/*.st must translate, compile with -Werror and produce the
(* EXPECT path = value *) values after (* SCANS n *) scans; reject/*.st must fail with the
(* ERROR line:col: message *) diagnostics."""
import glob
import os

import pytest
from stc.semantics import SEMANTICS

import stc_harness as H

ACCEPT = sorted(glob.glob(os.path.join(H.HERE, "accept", "*.st")))
REJECT = sorted(glob.glob(os.path.join(H.HERE, "reject", "*.st")))


def _id(p):
    return os.path.splitext(os.path.basename(p))[0]


@pytest.mark.parametrize("semantics", SEMANTICS)
@pytest.mark.parametrize("path", ACCEPT, ids=_id)
def test_accept(path, semantics, tmp_path):
    H.check_accept(path, tmp_path, semantics)


@pytest.mark.parametrize("path", REJECT, ids=_id)
def test_reject(path, tmp_path):
    H.check_reject(path, tmp_path)


def test_corpus_sizes():
    # the issue asks for substantial corpora; keep them from shrinking silently
    assert len(ACCEPT) >= 60, len(ACCEPT)
    assert len(REJECT) >= 60, len(REJECT)
