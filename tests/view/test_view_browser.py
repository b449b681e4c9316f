"""mip-view in a real browser (Debian's Chromium through Playwright): the tests click what a
trainer clicks and check what the page shows against the co-simulation's own trace
(/api/trace: the emulator's lines and chainsim's plc lines of the same run). The quick tier
keeps one short test; the presets (with their screenshots in build/view/), the follow mode and
the restart buttons are full tier."""
from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from view_helpers import all_chunks_drawn, needs_browser
from mipcosim.trace import parse, read_trace
from mipview import session as S
from mipview import shots

REPO = Path(__file__).resolve().parents[2]
pytestmark = needs_browser


@pytest.fixture
def server(view_workdir):
    srv = shots.Server("--preset", "clean", workdir=view_workdir)
    yield srv
    srv.close()


@pytest.fixture
def page(browser, server):
    pg = browser.new_page(viewport=shots.VIEWPORT)
    pg.goto(server.url)
    pg.wait_for_selector("#block-outstation td[data-var=eState]")
    yield pg
    pg.close()


def trace(server):
    return parse(server.get("api/trace").splitlines(), "api/trace")


def svg_texts(pg):
    return pg.locator("#diagram svg text").all_text_contents()


def settle(pg, server):
    """Waits until the page's controls are answered and it has drawn the server's latest
    state."""
    pg.wait_for_function("(document.body.dataset.pending || '0') === '0'")
    v = json.loads(server.get("api/state"))["version"]
    pg.wait_for_function(f"Number(document.body.dataset.version) >= {v}")


def test_step_lose_a_record_and_see_it(page, server):
    """Paused at the start: single scans until the outstation's write of record 1 lands in the
    TRM (its register highlighted, the block's state MIP_SND_WAIT_ACK), then 'lose the next
    record' and radio slots until the diagram shows the record LOST, as the trace has it."""
    pg = page
    assert pg.inner_text("#status") == "paused" and pg.inner_text("#time") == "0"
    for _ in range(10):
        pg.click("#step-scan")
        settle(pg, server)
        if pg.inner_text("#registers td[data-addr='2001']") == "1":
            break
    cell = pg.locator("#registers td[data-addr='2001']")
    assert cell.inner_text() == "1" and cell.get_attribute("class") == "changed"
    t_ms = int(pg.inner_text("#time"))
    writes = [d for d in trace(server) if d["ev"] == "modbus" and d.get("fc") == 16
              and d["ep"] == "trm"]
    assert [(d["w0"], d["t"] < t_ms * S.MS) for d in writes] == [(1, True)]
    state = pg.inner_text("#block-outstation td[data-var=eState]")
    assert state == "MIP_SND_WAIT_ACK" and state in S.ENUMS["E_MIP_SenderState"]

    pg.click("#lose-record")
    settle(pg, server)
    assert "armed" in pg.get_attribute("#lose-record", "class")
    for _ in range(6):
        pg.click("#step-slot")
        settle(pg, server)
        if any("LOST" in t for t in svg_texts(pg)):
            break
    lost = [d for d in trace(server) if d["ev"] == "radio" and d.get("lost")]
    assert len(lost) == 1 and lost[0]["dir"] == "up" and lost[0]["r0"] == 1
    assert "answer: record 1 (123 regs): LOST" in svg_texts(pg)
    # the time column shows the lost telegram's time, from the trace
    assert f"{lost[0]['t'] // S.MS} ms" in svg_texts(pg)
    assert pg.inner_text("#radio-table").split("\n")[-1].split("\t")[-1] == "1"
    assert "armed" not in (pg.get_attribute("#lose-record", "class") or "")


@pytest.mark.slow
def test_every_preset_runs_in_the_page(page, server):
    """Each exercise's preset, started from the page's list, runs to the end at the top speed;
    the page's diagram is the trace's and the blocks end done."""
    pg = page
    pg.select_option("#speed", "50")
    settle(pg, server)
    for name in S.PRESETS:
        pg.select_option("#preset", name)
        pg.click("#start-preset")
        settle(pg, server)
        pg.wait_for_function(f"document.getElementById('title').textContent === "
                             f"{json.dumps(S.PRESETS[name].title)}")
        if pg.inner_text("#pause") == "Resume":
            pg.click("#pause")
        pg.wait_for_function("document.getElementById('status').textContent === "
                             "'transfer complete'", timeout=60_000)
        pg.click("#pause")
        settle(pg, server)
        all_chunks_drawn(pg, server)            # ex8 has more than one chunk
        tr = trace(server)
        rows = S.rows_of(tr)               # the whole run, every row
        texts = svg_texts(pg)
        for _, _, d in rows:
            assert S.seqdiag.mark_reset(d["text"]) in texts or d["text"] in texts, (name, d)
        assert pg.inner_text("#block-outstation td[data-var=eState]") == "MIP_SND_DONE", name
        assert pg.inner_text("#block-central td[data-var=eState]") == "MIP_RCV_COMPLETE", name
        lost = sum(bool(d.get("lost")) for d in tr if d["ev"] == "radio")
        p = S.PRESETS[name]
        assert (lost > 0) == bool(p.loss_up or p.loss_down or p.lose_record), name
        restarts = [d for d in tr if d.get("what") == "restart"]
        assert [d["side"] for d in restarts] == ([p.restart] if p.restart else []), name


@pytest.mark.slow
def test_restart_buttons_and_speed(page, server):
    pg = page
    server.control(action="advance", ms=700)
    pg.click("#restart-central-warm")
    pg.wait_for_selector("#block-central.off")
    assert "PLC off for 1000 ms (warm restart)" in svg_texts(pg)
    server.control(action="advance", ms=1000)
    settle(pg, server)
    assert pg.locator("#block-central.off").count() == 0
    assert "PLC on again, its memory kept" in svg_texts(pg)
    pg.click("#restart-outstation-cold")
    settle(pg, server)
    assert "PLC restarted" in svg_texts(pg)
    pg.select_option("#speed", "10")
    settle(pg, server)
    pg.click("#pause")                                   # Resume
    pg.wait_for_function("document.getElementById('status').textContent === "
                         "'transfer complete'", timeout=60_000)
    st = json.loads(server.get("api/state"))
    assert st["speed"] == 10 and not st["paused"]
    tr = trace(server)
    assert [d["text"] for d in tr if d.get("what") == "restart"] == [
        "PLC off for 1000 ms (warm restart)", "PLC on again, its memory kept", "PLC restarted"]


@pytest.mark.slow
def test_a_choice_in_the_lists_stays_while_the_run_goes_on(page, server):
    """The page redraws ten times a second; the preset a trainer is choosing is not reset."""
    pg = page
    pg.click("#pause")                                   # Resume
    settle(pg, server)
    pg.select_option("#preset", "ex4")
    v = json.loads(server.get("api/state"))["version"]
    pg.wait_for_function(f"Number(document.body.dataset.version) >= {v + 3}")
    assert pg.input_value("#preset") == "ex4"
    assert json.loads(server.get("api/state"))["preset"] == "clean"
    pg.click("#start-preset")
    settle(pg, server)
    assert json.loads(server.get("api/state"))["preset"] == "ex4"


@pytest.mark.slow
def test_bad_control_shows_one_line(page, server):
    pg = page
    pg.evaluate("control({action: 'lose', what: 'everything'})")
    pg.wait_for_function("document.getElementById('message').textContent !== ''")
    assert pg.inner_text("#message") == "lose 'everything': record or ack"


@pytest.mark.slow
def test_follow_mode_shows_a_growing_trace(browser, view_workdir, tmp_path):
    """Read-only: the page follows a trace file as mipsim's run is appended to it."""
    full = tmp_path / "full.jsonl"
    r = subprocess.run([sys.executable, str(REPO / "docs/tools/mipsim.py"), "--records", "3",
                        "--loss-up", "0.3", "--seed", "3", "--trace", str(full)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = full.read_text().splitlines(keepends=True)
    path = tmp_path / "live.jsonl"
    path.write_text("".join(lines[:len(lines) // 2]))
    srv = shots.Server("--follow", str(path), paused=False)
    try:
        pg = browser.new_page(viewport=shots.VIEWPORT)
        pg.goto(srv.url)
        pg.wait_for_selector("#radio-table")
        assert pg.locator("#restart-central-cold").is_hidden()     # read-only
        with open(path, "a") as f:
            f.write("".join(lines[len(lines) // 2:]))
        want = [d["text"] for _, _, d in S.rows_of(parse(lines))]
        deadline = time.time() + 10
        while time.time() < deadline and want[-1] not in svg_texts(pg):
            time.sleep(0.1)
        texts = svg_texts(pg)
        assert all(w in texts or S.seqdiag.mark_reset(w) in texts for w in want)
        lost_up = sum(1 for x in lines if '"lost":true' in x and '"dir":"up"' in x)
        assert f"{lost_up}" in pg.inner_text("#radio-table") and lost_up > 0
        pg.click("#pause")                   # stops redrawing: what is appended waits
        settle(pg, srv)
        shown = pg.inner_text("#radio-table")
        with open(path, "a") as f:
            f.write(json.dumps({"t": 10**12, "ev": "radio", "kind": "answer", "dir": "up",
                                "st": 1, "t0": 0, "bytes": 258, "regs": 123, "r0": 7,
                                "lost": True}) + "\n")
        time.sleep(0.5)
        assert pg.inner_text("#radio-table") == shown
        pg.click("#pause")                   # Resume
        pg.wait_for_function("document.querySelector('#diagram svg').textContent"
                             ".includes('answer: [0]=7 (123 regs): LOST')")
        r = pg.evaluate("fetch('/api/control', {method: 'POST', headers: {'Content-Type': "
                        "'application/json'}, body: JSON.stringify({action: 'step_scan'})})"
                        ".then(r => r.json())")
        assert r == {"error": "step_scan: the view follows a trace (read-only)"}
        r = pg.evaluate("fetch('/api/control', {method: 'POST', body: "
                        "JSON.stringify({action: 'pause'})}).then(r => r.status)")
        assert r == 415                     # not JSON: what another site's page could send
        pg.close()
    finally:
        srv.close()


@pytest.mark.slow
def test_demo_in_real_time_is_followed_and_stopped_with_the_view(browser):
    """--demo: the real-time demo (plc/demo.py: soft PLCs and mip-emulator over Modbus TCP)
    started by the view, its trace followed as it grows; the demo's result line on the page;
    stopping the view stops the demo."""
    srv = shots.Server("--demo", "--records 3", paused=False)
    try:
        pid = int(re.search(r"pid (\d+)", srv.said[0]).group(1))
        pg = browser.new_page(viewport=shots.VIEWPORT)
        pg.goto(srv.url)
        pg.wait_for_function("document.getElementById('note').textContent.startsWith('result:')",
                             timeout=120_000)
        assert pg.inner_text("#note").startswith("result: ok records=3 ")
        trace_file = REPO / "build" / "view" / "demo" / "emulator-trace.jsonl"
        events = read_trace(trace_file)
        settle(pg, srv)
        lost = [d for d in events if d["ev"] == "radio" and d.get("lost")]
        assert [d["r0"] for d in lost] == [2]          # the demo's record 2, lost once
        want = [d["text"] for _, _, d in S.rows_of(events)]
        texts = svg_texts(pg)
        assert all(w in texts or S.seqdiag.mark_reset(w) in texts
                   for w in want)
        pg.close()
        # a long demo, stopped with the view: its processes end too
        srv.close()
        srv = shots.Server("--demo", "--records 500 --realistic", paused=False)
        pid = int(re.search(r"pid (\d+)", srv.said[0]).group(1))
        time.sleep(1)
        assert Path(f"/proc/{pid}").exists()
    finally:
        srv.close()
    deadline = time.time() + 20
    while time.time() < deadline and Path(f"/proc/{pid}").exists():
        time.sleep(0.1)
    assert not Path(f"/proc/{pid}").exists(), "the demo outlived the view"


@pytest.mark.slow
def test_screenshots_of_the_presets_match_the_docs(browser, view_workdir):
    """The generator of docs/img/view-*.png, run here into build/view/: the same pictures (what
    each shows, written into it; its size) as the committed ones."""
    out = shots.take(REPO / "build" / "view", workdir=view_workdir, browser=browser)
    assert set(out) == set(S.PRESETS) | set(S.CHAINS)
    assert all(path.is_file() for path, _ in out.values())
    for name in shots.DOCS_PRESETS:
        path = out[name][0]
        committed = REPO / "docs" / "img" / path.name
        assert committed.is_file(), f"{committed} missing: make view-shots"
        assert shots.png_text(path) == shots.png_text(committed), name
        assert shots.png_size(path) == shots.png_size(committed) == (
            shots.VIEWPORT["width"], shots.VIEWPORT["height"])
