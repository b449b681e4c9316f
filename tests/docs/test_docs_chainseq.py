"""docs/img/seq-chain-one-event.svg (docs/chain.md, "The whole chain") is drawn by
docs/tools/chainseq.py from the checked-in trace docs/traces/chain-one-event.jsonl, which the
same tool writes from a co-simulated run of the chain: both must be up to date."""
import json
import subprocess
import sys

import pytest
from lxml import etree

from docs_helpers import REPO

TOOL = REPO / "docs" / "tools" / "chainseq.py"
TRACE = REPO / "docs" / "traces" / "chain-one-event.jsonl"
SVG = REPO / "docs" / "img" / "seq-chain-one-event.svg"


def chainseq(*args):
    return subprocess.run([sys.executable, str(TOOL), *map(str, args)], capture_output=True,
                          text=True, timeout=300)


def test_chain_diagram_is_drawn_from_the_checked_in_trace(tmp_path):
    r = chainseq("draw", TRACE, "-o", tmp_path / "seq.svg")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "seq.svg").read_bytes() == SVG.read_bytes(), \
        "docs/img/seq-chain-one-event.svg is stale: run docs/tools/chainseq.py draw and commit it"
    texts = [t.text for t in etree.parse(str(SVG)).getroot().iter("{http://www.w3.org/2000/svg}text")]
    # the order the chain promises: stored before the relay deletes, the SCADA before the radio ack
    order = [next(i for i, t in enumerate(texts) if t and t.startswith(p)) for p in (
        "MIP_SoeReader -> PLC_SoeLog: stored", "entry deleted", "stored: value 1",
        "MIP_SoeServer: acknowledged", "FC16: acknowledge 1", "transfer done")]
    assert order == sorted(order), texts


def test_chain_trace_steps_keep_the_promises():
    steps = [json.loads(l) for l in TRACE.read_text().splitlines()]
    at = {s["label"]: s["t"] for s in steps}
    # the relay deletes only what the logger stored; the radio acknowledgement of the record
    # goes out only after the SCADA acknowledged its entry
    assert at["MIP_SoeReader -> PLC_SoeLog: stored (RETAIN)"] <= at["entry deleted, sequence number raised"]
    assert at["FC6 SOE_Control := 1 + 1*256"] < at["FC16: acknowledge 1"]
    scada = next(s for s in steps if s.get("note") == "scada")
    assert scada["label"] == "stored: value 1, time stamp 1767225600500 ms"   # the relay's stamp


def test_a_bad_trace_is_one_line(tmp_path):
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"t": 1, "note": "nowhere", "label": "x"}\n')
    r = chainseq("draw", bad, "-o", tmp_path / "x.svg")
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "step 1" in r.stderr
    bad.write_text("not json\n")
    r = chainseq("draw", bad, "-o", tmp_path / "x.svg")
    assert r.returncode == 1 and f"{bad}:1: not a JSON line" in r.stderr


@pytest.mark.slow
def test_chain_trace_is_what_the_chain_does_now(tmp_path):
    r = chainseq("trace", tmp_path / "t.jsonl", "--workdir", tmp_path / "w")
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "t.jsonl").read_text() == TRACE.read_text(), \
        "docs/traces/chain-one-event.jsonl is stale: run docs/tools/chainseq.py trace and commit it"
