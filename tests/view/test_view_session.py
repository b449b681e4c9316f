"""mip-view without a browser: its runs are the docs' chain's (the same trace as mipsim for the
same options), its controls do what they say on the emulator's own trace, a followed trace is
read as it grows, and bad options and controls give one line, never a traceback."""
from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from mipcosim.trace import parse
from mipview import session as S

REPO = Path(__file__).resolve().parents[2]
PY = sys.executable
MIPSIM = REPO / "docs" / "tools" / "mipsim.py"


def run_to_end(s, limit_ms=60_000):
    while not s.done and s.t_ms < limit_ms:
        s.step()
    assert s.done, f"{s.preset_name}: not complete after {limit_ms} ms"


def lines(trace):
    return parse(trace)


def test_a_preset_is_the_exercise_run_of_mipsim(view_workdir, tmp_path):
    """The page's run of a preset is mipsim's run with the same options: the same trace, line
    for line (one kernel, no second model), up to the same virtual time."""
    s = S.Live("ex2", view_workdir)
    run_to_end(s)
    s.advance(300)                        # mipsim runs on 300 ms after the end
    ours = s.trace()
    s.close()
    out = tmp_path / "ex2.jsonl"
    r = subprocess.run([PY, str(MIPSIM), *S.PRESETS["ex2"].mipsim_args().split(),
                        "--trace", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    theirs = out.read_text().splitlines()
    assert len(ours) == len(theirs) and ours == theirs


def test_lose_the_next_record_loses_exactly_that_telegram(view_workdir):
    s = S.Live("clean", view_workdir)
    s.lose("record")
    run_to_end(s)
    tr = lines(s.trace())
    lost = [d for d in tr if d["ev"] == "radio" and d.get("lost")]
    # the demo has no loss of its own: the one lost telegram is the first that carried a record
    first_up_block = next(d for d in tr if d["ev"] == "radio" and d["dir"] == "up" and d["regs"])
    assert lost == [first_up_block] and first_up_block["r0"] == 1
    assert s.lost_by_view == [(s.lost_by_view[0][0], "up", 1)]
    # the diagram says so in its words, and the data still arrived
    assert "answer: record 1 (123 regs): LOST" in [r["text"] for r in s.state()["rows"]]
    assert s.c.transfers == [s.data]
    s.close()


def test_the_demo_preset_loses_record_2_once_as_make_run_does(view_workdir):
    s = S.Live("demo", view_workdir)
    run_to_end(s)
    tr = lines(s.trace())
    lost = [d for d in tr if d["ev"] == "radio" and d.get("lost")]
    assert [(d["dir"], d["r0"]) for d in lost] == [("up", 2)]
    assert s.c.transfers == [s.data] and s.o.fbv("udiRetransmissions") == 0
    assert "record 2 lost once" in s.state()["mipsim"]
    s.close()


def test_lose_the_next_ack_and_extra_loss(view_workdir):
    s = S.Live("clean", view_workdir)
    s.advance(400)                        # record 1 is on its way
    s.lose("ack")
    n = len(s.ch.lines)
    run_to_end(s)
    after = [d for d in lines(s.trace())[n:] if d["ev"] == "radio" and d.get("lost")]
    assert len(after) == 1 and after[0]["dir"] == "down" and after[0]["regs"]
    assert s.c.transfers == [s.data]
    s.close()
    # extra loss 1.0 uplink: no record gets through, the sender waits
    s = S.Live("clean", view_workdir)
    s.set_loss("up", 1.0)
    s.advance(3000)
    st = s.state()
    assert st["radio"]["lost_up"] > 0 and s.c.received == []
    assert st["blocks"][0]["vars"][0]["value"] == "MIP_SND_WAIT_ACK"
    s.set_loss("up", 0.0)
    run_to_end(s)
    assert s.c.transfers == [s.data]
    s.close()


def test_warm_restart_keeps_the_state_cold_restart_loses_it(view_workdir):
    s = S.Live("clean", view_workdir)
    s.advance(700)                         # record 1 delivered
    before = s.c.fbv("udiRecords")
    assert before == 1
    s.restart("central", "warm", 500)
    assert s.state()["blocks"][1]["off"]
    s.advance(200)
    with pytest.raises(S.ViewError, match="off already"):
        s.restart("central", "cold")
    s.advance(400)
    assert not s.off and s.c.fbv("udiRecords") >= before     # its memory kept
    run_to_end(s)
    texts = [d.get("text") for d in s.ch.lines if d.get("what") == "restart"]
    assert texts == ["PLC off for 500 ms (warm restart)", "PLC on again, its memory kept"]
    assert s.c.fbv("udiFailedTransfers") == 0 and s.o.errors == []
    s.close()
    s = S.Live("clean", view_workdir)
    s.advance(700)
    s.restart("central", "cold")
    s.step()
    assert s.c.fbv("udiRecords") == 0
    st = s.state()
    assert st["blocks"][1]["vars"][0]["value"] in S.ENUMS["E_MIP_ReceiverState"]
    s.close()


def test_register_windows_show_the_emulator_and_mark_changes(view_workdir):
    s = S.Live("clean", view_workdir)
    s.state()
    s.advance(30)                           # the outstation wrote record 1 at 20 ms
    w = {x["start"]: x for x in s.state()["registers"]}
    trm = w[2000]
    assert trm["values"][1] == 1 and 1 in trm["changed"]
    assert trm["values"][2:9] == s.data[:7]
    again = {x["start"]: x for x in s.state()["registers"]}[2000]
    assert again["changed"] == []           # nothing changed since the last look
    s.close()


@pytest.mark.parametrize("bad, why", [
    (lambda s: s.lose("nothing"), "record or ack"),
    (lambda s: s.set_loss("sideways", 0.1), "up or down"),
    (lambda s: s.set_loss("up", 1.5), "0..1"),
    (lambda s: s.set_speed(3), "one of"),
    (lambda s: s.restart("plant", "cold"), "outstation or central"),
    (lambda s: s.restart("central", "lukewarm"), "cold or warm"),
    (lambda s: s.advance(0), "1..600000"),
    (lambda s: s.restart("central", "warm"), "the central PLC has not started yet (it starts at 50 ms)"),
])
def test_bad_controls_say_what_is_wrong(view_workdir, bad, why):
    s = S.Live("clean", view_workdir)
    with pytest.raises(S.ViewError, match=re.escape(why)):
        bad(s)
    s.close()


def test_follow_reads_a_trace_as_it_grows(tmp_path):
    path = tmp_path / "t.jsonl"
    radio = {"t": 305_000_000, "ev": "radio", "kind": "answer", "dir": "up", "st": 1,
             "t0": 0, "bytes": 258, "regs": 123, "r0": 1, "lost": True}
    path.write_text("")
    f = S.Follow(path)
    assert f.state()["rows"] == []
    text = json.dumps(radio)
    path.write_text(text[:20])                   # a line still being written
    assert f.poll() and f.events == []
    path.write_text(text + "\n")
    f.poll()
    st = f.state()
    assert [r["text"] for r in st["rows"]] == ["answer: [0]=1 (123 regs): LOST"]
    assert st["radio"] == {"down": 0, "up": 1, "lost_down": 0, "lost_up": 1}
    with open(path, "a") as fh:
        fh.write("not json\n")
    f.poll()
    assert f.state()["bad"] == f"{path}:2:1: not a JSON line: Expecting value"
    path.write_text("")                          # a new run truncated it: start over
    f.poll()
    assert f.events == [] and f.state()["lines"] == 0


def mipview(*args, timeout=20):
    return subprocess.run([PY, "-m", "mipview.server", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=REPO)


def test_command_line_errors_are_one_line(tmp_path):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        r = mipview("--port", str(port), "--follow", str(REPO / "docs/traces/note-2-1-1.jsonl"))
    assert r.returncode == 2
    assert r.stderr == f"mip-view: error: cannot listen on 127.0.0.1:{port}: in use " \
                       f"(another mip-view? use --port)\n"
    for args, msg in [(["--follow", str(tmp_path / "none.jsonl")], "no such trace file"),
                      (["--preset", "ex99"], "invalid choice"),
                      (["--speed", "3"], "--speed must be one of"),
                      (["--port", "70000"], "--port must be 0..65535")]:
        r = mipview(*args)
        assert r.returncode == 2 and msg in r.stderr and "Traceback" not in r.stderr, args
        assert len(r.stderr.strip().splitlines()[-1]) > 0


def test_follow_a_compressed_trace_and_another_station(tmp_path):
    """The test kit's report keeps the trace around a fault as .jsonl.gz; a network of several
    stations is drawn one station at a time."""
    import gzip
    lines = [{"t": 10_000_000 * (i + 1), "ev": "radio", "kind": "answer", "dir": "up", "st": st,
              "t0": 0, "bytes": 258, "regs": 123, "r0": i + 1, "lost": st == 2}
             for i, st in enumerate([1, 2, 2])]
    path = tmp_path / "kit.jsonl.gz"
    with gzip.open(path, "wt") as f:
        f.write("\n".join(json.dumps(d) for d in lines))     # no newline at the end
    one, two = S.Follow(path), S.Follow(path, station=2)
    assert [r["text"] for r in one.state()["rows"]] == ["answer: [0]=1 (123 regs)"]
    assert [r["text"] for r in two.state()["rows"]] == ["answer: [0]=2 (123 regs): LOST",
                                                        "answer: [0]=3 (123 regs): LOST"]
    assert two.state()["radio"]["lost_up"] == 2 and not two.poll()
    with pytest.raises(S.ViewError, match="station must be 1..247"):
        S.Follow(path, station=0)
    bad = tmp_path / "cut.jsonl.gz"
    bad.write_bytes(path.read_bytes()[:30])
    assert S.Follow(bad).bad.startswith(f"{bad}: ")
