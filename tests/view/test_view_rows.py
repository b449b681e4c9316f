"""What the page's rows say (view/mipview/rows.py) and a followed trace with bytes that are no
trace: without a browser, quick."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from mipcosim.trace import read_trace

from mipview import session as S

REPO = Path(__file__).resolve().parents[2]
NOTE = REPO / "docs" / "traces" / "note-2-1-1.jsonl"


def texts(rows):
    return [d["text"] for _, _, d in rows]


def run_to_end(s, limit_ms=60_000):
    while not s.done and s.t_ms < limit_ms:
        s.step()
    assert s.done


def test_the_demo_in_the_notes_words_with_the_modems_repeat_marked(view_workdir):
    s = S.Live("demo", view_workdir)
    run_to_end(s)
    t = texts(S.rows_of(s.ch.lines))
    s.close()
    # record 2 is lost once on its way up; the modem sends the same block at the next poll
    lost = t.index("answer: record 2 (123 regs): LOST")
    assert t[lost + 1] == "answer: record 2 (123 regs) (modem repeat)"
    assert sum("modem repeat" in x for x in t) == 1
    assert not any("retransmission" in x for x in t)     # the PLC wrote record 2 once
    assert "write record 16#FFFF (last) (123 regs)" in t
    assert "write ack 0 (start) + echo (3 regs)" in t and "write ack 2 (1 reg)" in t
    assert "radio ack: block confirmed" in t
    assert not any("65535" in x for x in t)


@pytest.mark.parametrize("preset", ["ex2", "ex4", "ex5"])
def test_our_retransmission_is_marked_apart_from_the_modems_repeat(view_workdir, preset):
    """Exercise 4: a timeout too short for the link, so MIP_Sender writes a record again (and
    2, 5: polled, bursts); every write marked is one of its udiRetransmissions."""
    s = S.Live(preset, view_workdir)
    run_to_end(s)
    rows = S.rows_of(s.ch.lines)
    retrans = s.o.fbv("udiRetransmissions")
    s.close()
    marked = [d for _, kind, d in rows if d["repeat"] == "block" and kind == "mb_write"
              and d["side"] == "outstation"]
    assert retrans > 0 and len(marked) == retrans
    assert all(d["text"].endswith("(retransmission by MIP_Sender)") for d in marked)
    modem = [d for _, kind, d in rows if d["repeat"] == "modem"]
    assert all(kind == "radio" for _, kind, d in rows if d["repeat"] == "modem")
    assert not any("retransmission" in d["text"] for d in modem)


def test_a_trace_of_the_emulator_alone_says_record_and_ack(tmp_path):
    """The real-time demo's and the chain demo's traces have no PLC lines: the blocks are
    labelled from the write registers (2001 a record, 10 an acknowledgement)."""
    events = read_trace(NOTE)
    raw = [d for d in events if d["ev"] != "plc"]
    t = texts(S.rows_of(raw))
    assert not any(x.startswith("FC16 write") for x in t)
    assert "write record 1 (123 regs)" in t and "write ack 0 (start) + echo (3 regs)" in t
    assert "answer: record 1 (123 regs)" in t and "poll: ack 1 + echo (3 regs)" in t
    assert "write record 16#FFFF (last) (50 regs)" in t


def test_the_history_is_kept_whole_in_chunks(view_workdir):
    s = S.Live("ex8", view_workdir)
    while s.state()["nrows"] <= S.CHUNK + 10:
        s.advance(500)
    first = s.state()
    run_to_end(s)
    st = s.state()
    s.close()
    assert st["nrows"] > 2 * S.CHUNK and len(st["chunks"]) == -(-st["nrows"] // S.CHUNK)
    assert [c["first"] for c in st["chunks"]] == list(range(1, st["nrows"] + 1, S.CHUNK))
    # a full chunk does not change as the run goes on (the page fetches it once)
    assert first["chunks"][0]["key"] == st["chunks"][0]["key"]
    svg0 = s.history.svg(0)
    assert ">write record 1 (123 regs)<" in svg0 and "Rows 1–100 of" in svg0


def test_a_byte_that_is_not_utf8_is_one_line_and_the_trace_is_read_on(tmp_path):
    lines = NOTE.read_bytes().splitlines(keepends=True)
    path = tmp_path / "t.jsonl"
    path.write_bytes(b"".join(lines[:100]))
    logged = []
    f = S.Follow(path, on_bad=logged.append)
    assert len(f.events) == 100 and f.bad_lines == []
    with open(path, "ab") as fh:
        fh.write(b'{"t": 1, "ev": "radio\xff"}\n' + b"".join(lines[100:]))
    assert f.poll()
    want = f"{path}:101:22: not UTF-8 (byte 16#FF): line skipped"
    assert f.state()["bad_lines"] == logged == [want]
    assert len(f.events) == len(lines) and f.state()["lines"] == len(lines)
    assert f.state()["rows"][-1]["text"] == S.rows_of(f.events)[-1][2]["text"]


def test_a_binary_file_at_start_is_one_line_per_line_no_traceback(tmp_path):
    path = tmp_path / "bin.jsonl"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\xff\xd8\n" + NOTE.read_bytes().splitlines(True)[0])
    p = subprocess.Popen([sys.executable, "-m", "mipview.server", "--port", "0", "--follow",
                          str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        said = p.stdout.readline()
        assert "open http://127.0.0.1:" in said
    finally:
        p.terminate()
        p.wait(10)
    err = p.stderr.read()
    assert "Traceback" not in err
    assert err.splitlines() == [f"mip-view: {path}:1:1: not UTF-8 (byte 16#89): line skipped",
                                f"mip-view: {path}:2:1: not a JSON line: Expecting value",
                                f"mip-view: {path}:3:3: not UTF-8 (byte 16#FF): line skipped"]


def test_register_windows_are_named_and_counters_in_the_notes_words(view_workdir):
    s = S.Live("clean", view_workdir)
    run_to_end(s)
    st = s.state()
    s.close()
    for w in st["registers"]:
        assert len(w["names"]) == len(w["tips"]) == len(w["values"]) and all(w["tips"])
    mdp = {w["start"]: w for w in st["registers"]}[9]
    # registers 11 and 12 of the MDP's write area: our receiver's echo (P8)
    assert mdp["names"][:4] == ["count", "ack", "echo", "check"]
    assert mdp["values"][2] == 0x4D50 and mdp["shown"][2] == "16#4D50"
    assert mdp["shown"][1] == "16#FFFF" and "16#4D50" in mdp["tips"][2]
    blocks = {b["side"]: {v["name"]: v["value"] for v in b["vars"]} for b in st["blocks"]}
    assert blocks["outstation"]["wRecord"] == "16#FFFF (last)"
    assert blocks["central"]["wAck"] == "16#FFFF (last)"
