"""What the sequence diagrams mark (docs/tools/seqdiag.py), on diagrams rendered here from the
checked-in traces (the reset record on a small trace of its own): the discarded duplicate, time jumps, and no note box
covering an arrow label."""
import json
import re

import pytest
from lxml import etree

from docs_helpers import tool

SVG = "{http://www.w3.org/2000/svg}"
NAMES = ["note-2-1-1", "bidirectional", "restart", "static-openplc", "pipelined",
         "pipelined-slow-central"]


def parse(path):
    root = etree.parse(str(path)).getroot()
    texts = [(t.text, float(t.get("x")), float(t.get("y")), t.get("fill"), t.get("text-anchor"),
              float(t.get("font-size"))) for t in root.iter(f"{SVG}text")]
    notes = [tuple(float(r.get(k)) for k in ("x", "y", "width", "height"))
             for r in root.iter(f"{SVG}rect") if r.get("rx") == "4"]
    return texts, notes


def test_reset_record_is_named_and_orange(tmp_path):
    # our senders open with record 1 now (st_lib/PROTOCOL.md P6); an older sender's reset
    # record 0 (P16) must still not look like an idle block
    trace = tmp_path / "t.jsonl"
    lines = [{"t": 0, "ev": "plc", "side": "outstation", "what": "write",
              "text": "write record 0 (2 regs)", "value": [0]},
             {"t": 0, "ev": "modbus", "ep": "trm", "st": 1, "unit": 1, "tid": 1, "fc": 16,
              "wa": 2001, "wq": 2, "w0": 0, "exc": 0},
             {"t": 10_000_000, "ev": "plc", "side": "central", "what": "write",
              "text": "write ack 0 (3 regs)", "value": [0]}]
    trace.write_text("\n".join(json.dumps(d) for d in lines) + "\n")
    r = tool("seqdiag", trace, "-o", tmp_path / "t.svg")
    assert r.returncode == 0, r.stderr
    texts, _ = parse(tmp_path / "t.svg")
    resets = [(s, fill) for s, _, _, fill, _, _ in texts if "RESET record 0" in s]
    assert resets == [("write RESET record 0 (2 regs)", "#d35400")]
    # the acknowledgement of the reset is an ordinary block
    assert not any("RESET" in s for s, *_ in texts if s.startswith("write ack 0"))


def test_discarded_duplicate_is_marked_once(diagrams):
    texts, _ = parse(diagrams / "seq-note-2-1-1.svg")
    dups = [s for s, *_ in texts if "again: discarded" in s]
    assert dups == ["record 2 again: discarded (already delivered)"]
    # after a restart the records 1, 2 come again in a new session: not duplicates
    texts, _ = parse(diagrams / "seq-restart.svg")
    assert not [s for s, *_ in texts if "again: discarded" in s]


@pytest.mark.parametrize("name", NAMES)
def test_time_jumps_are_shown(diagrams, name):
    # since sessions open with record 1 (no quiet wait) the checked-in traces have no long
    # gap; test_a_long_gap_in_a_small_trace draws one
    texts, _ = parse(diagrams / f"seq-{name}.svg")
    times = [(s, y) for s, _, y, _, _, _ in texts if re.fullmatch(r"\d+ ms", s)]
    jumps = [(s, y) for s, _, y, _, _, _ in texts if re.fullmatch(r"\+\d+ ms", s)]
    # every jump label sits between two row times that are that far apart
    for s, y in jumps:
        before = max((t for t in times if t[1] < y), key=lambda t: t[1])
        after = min((t for t in times if t[1] > y), key=lambda t: t[1])
        assert int(after[0].split()[0]) - int(before[0].split()[0]) == int(s[1:].split()[0])
    # and no two consecutive rows JUMP_MS or more apart go without one
    from mipdocs import seqdiag
    ms = [(int(s.split()[0]), y) for s, y in times]
    for (t1, y1), (t2, y2) in zip(ms, ms[1:]):
        if t2 - t1 >= seqdiag.JUMP_MS:
            assert any(y1 < y < y2 for _, y in jumps), (t1, t2)


def test_a_long_gap_in_a_small_trace(tmp_path):
    trace = tmp_path / "t.jsonl"
    lines = [{"t": 0, "ev": "modbus", "ep": "trm", "st": 1, "fc": 16, "w0": 1, "wq": 3},
             {"t": 75_000_000_000, "ev": "modbus", "ep": "trm", "st": 1, "fc": 16, "w0": 2,
              "wq": 3}]
    trace.write_text("\n".join(json.dumps(d) for d in lines) + "\n")
    r = tool("seqdiag", trace, "-o", tmp_path / "t.svg")
    assert r.returncode == 0, r.stderr
    texts, _ = parse(tmp_path / "t.svg")
    assert "+75.0 s" in [s for s, *_ in texts]


@pytest.mark.parametrize("name", NAMES)
def test_no_note_covers_an_arrow_label(diagrams, name):
    texts, notes = parse(diagrams / f"seq-{name}.svg")
    labels = [(s, x, y, anchor, size) for s, x, y, _, anchor, size in texts
              if size == 11 and anchor == "middle"]
    note_texts = set()
    for nx, ny, nw, nh in notes:
        for s, x, y, _, _ in labels:
            if nx <= x <= nx + nw and ny <= y <= ny + nh:
                note_texts.add((s, y))            # the note's own text
    for nx, ny, nw, nh in notes:
        for s, x, y, _, size in labels:
            if (s, y) in note_texts:
                continue
            half = 0.33 * size * len(s)            # generous width of DejaVu Sans at 11 px
            top, bottom = y - 0.8 * size, y + 0.2 * size
            overlaps = x - half < nx + nw and x + half > nx and top < ny + nh and bottom > ny
            assert not overlaps, f"note at y={ny} covers the label {s!r} at y={y}"


# DejaVu Sans (the first font of the diagrams) advance widths in em, for the characters of the
# time labels; the other fonts of the list are narrower
_EM = {**{d: 0.636 for d in "0123456789"}, " ": 0.318, "m": 0.974, "s": 0.521, "+": 0.838,
       ".": 0.318}


def test_time_labels_of_a_long_run_are_not_clipped(tmp_path):
    """Runs longer than about 100 s: "1795111 ms" was drawn as "795111 ms" (left of the
    picture); the picture widens to the left for labels that long."""
    trace = tmp_path / "t.jsonl"
    lines = [{"t": 1_795_111_000_000, "ev": "modbus", "ep": "trm", "st": 1, "fc": 16, "w0": 1,
              "wq": 3},
             {"t": 1_795_131_000_000, "ev": "modbus", "ep": "trm", "st": 1, "fc": 16, "w0": 2,
              "wq": 3},
             {"t": 1_905_131_000_000, "ev": "modbus", "ep": "trm", "st": 1, "fc": 16, "w0": 3,
              "wq": 3}]
    trace.write_text("\n".join(json.dumps(d) for d in lines) + "\n")
    r = tool("seqdiag", trace, "-o", tmp_path / "t.svg")
    assert r.returncode == 0, r.stderr
    root = etree.parse(str(tmp_path / "t.svg")).getroot()
    left = float(root.get("viewBox").split()[0])
    texts, _ = parse(tmp_path / "t.svg")
    labels = [(s, x, size) for s, x, _, _, anchor, size in texts
              if anchor == "end" and re.fullmatch(r"\+?[\d.]+ m?s", s)]
    assert "1795111 ms" in [s for s, *_ in labels] and "+110.0 s" in [s for s, *_ in labels]
    for s, x, size in labels:
        width = size * sum(_EM[c] for c in s)
        assert x - width >= left, f"{s!r} starts at {x - width:.1f}, the picture at {left}"
