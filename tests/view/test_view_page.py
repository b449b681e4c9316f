"""What a trainer sees in the page (Debian's Chromium through Playwright), issue 44: the whole
history scrolled back to record 1 and searched, the note's 16#FFFF, the modem's repeat marked,
a deep link to an exercise's moment, the controls of a follow view as docs/view.md lists them,
and a followed trace with a byte that is not UTF-8 that goes on with the lines after it. The
quick tier keeps the scrollback, the deep link and the bad byte (a few seconds each); the
modem's repeat in the page and the live controls against the doc are full tier (the repeat's
label is checked without a browser in test_view_rows.py)."""
from __future__ import annotations

import json
import re
import time
from pathlib import Path

import pytest

from view_helpers import all_chunks_drawn, needs_browser
from mipcosim.trace import parse
from mipview import session as S
from mipview import shots

REPO = Path(__file__).resolve().parents[2]
NOTE = REPO / "docs" / "traces" / "note-2-1-1.jsonl"
VIEW_MD = (REPO / "docs" / "view.md").read_text()
pytestmark = needs_browser


def open_page(browser, srv, query=""):
    pg = browser.new_page(viewport=shots.VIEWPORT)
    pg.goto(srv.url + query)
    pg.wait_for_selector("#radio-table")
    return pg


def settle(pg, srv):
    pg.wait_for_function("(document.body.dataset.pending || '0') === '0'")
    v = json.loads(srv.get("api/state"))["version"]
    pg.wait_for_function(f"Number(document.body.dataset.version) >= {v}")


def svg_texts(pg):
    return pg.locator("#diagram svg text").all_text_contents()


def in_view(pg, text):
    """The label is inside the diagram's visible box (not scrolled away)."""
    return pg.evaluate("""(text) => {
        const box = document.getElementById('diagram-box').getBoundingClientRect();
        return [...document.querySelectorAll('#diagram svg text')].some((t) => {
            if (t.textContent !== text) return false;
            const r = t.getBoundingClientRect();
            return r.top >= box.top && r.bottom <= box.bottom;
        });
    }""", text)


def controls(pg):
    """The names of the controls the page shows: a button's text, a list's or a slider's
    label, a search field's placeholder up to its parenthesis, a link's text."""
    return pg.evaluate("""() => [...document.querySelectorAll(
            '#controls button, #controls select, #controls input, #controls a')]
        .filter((e) => e.offsetParent !== null)
        .map((e) => e.tagName === 'BUTTON' || e.tagName === 'A' ? e.textContent.trim()
             : e.placeholder ? e.placeholder.split(' (')[0]
             : e.closest('label').firstChild.textContent.trim())""")


def test_scroll_back_to_record_1_after_the_end_and_search(browser, view_workdir):
    """Exercise 8 (20 records, a few hundred rows): after the end the page shows the end;
    scrolled up, record 1 is there; the search finds the last record as the note writes it."""
    srv = shots.Server("--preset", "ex8", workdir=view_workdir)
    try:
        pg = open_page(browser, srv)
        while not srv.control(action="advance", ms=1000)["done"]:
            pass
        settle(pg, srv)
        st = all_chunks_drawn(pg, srv)
        assert st["nrows"] > 2 * S.CHUNK
        assert pg.inner_text("#status") == "paused"
        assert "xDone: last record acknowledged" in [r["text"] for r in st["rows"]]
        assert in_view(pg, st["rows"][-1]["text"])                  # it follows the end
        assert not in_view(pg, "write record 1 (123 regs)")
        pg.hover("#diagram-box")
        for _ in range(60):                                          # scroll up by wheel
            pg.mouse.wheel(0, -2000)
            if pg.evaluate("document.getElementById('diagram-box').scrollTop") == 0:
                break
        pg.wait_for_timeout(200)
        assert in_view(pg, "write record 1 (123 regs)")
        texts = svg_texts(pg)
        assert len([t for t in texts if t.startswith("write record ")]) >= 20
        assert not any("65535" in t for t in texts)
        assert "write record 16#FFFF (last) (123 regs)" in texts
        # the modem's repeats of blocks whose telegram or confirmation was lost, marked
        repeats = [t for t in texts if t.endswith("(modem repeat)")]
        assert repeats and all(t.startswith(("answer: ", "poll: ")) for t in repeats)
        assert pg.inner_text("#registers td[data-addr='2001']") == "16#FFFF"
        assert "16#4D50" in pg.get_attribute("#registers th:has-text('11')", "title")
        pg.fill("#search", "write record 16#FFFF")
        pg.press("#search", "Enter")
        assert pg.inner_text("#search-info") == "1 of 1"
        assert in_view(pg, "write record 16#FFFF (last) (123 regs)")
        pg.close()
    finally:
        srv.close()


@pytest.mark.slow
def test_the_modems_repeat_is_marked_and_found(browser, view_workdir):
    srv = shots.Server("--preset", "demo", workdir=view_workdir)
    try:
        pg = open_page(browser, srv)
        srv.control(action="advance", ms=1500)
        settle(pg, srv)
        texts = svg_texts(pg)
        i = texts.index("answer: record 2 (123 regs): LOST")
        assert "answer: record 2 (123 regs) (modem repeat)" in texts[i:]
        pg.fill("#search", "modem repeat")
        pg.press("#search", "Enter")
        assert pg.inner_text("#search-info") == "1 of 1"
        assert pg.text_content("#diagram svg text.current") == \
            "answer: record 2 (123 regs) (modem repeat)"
        pg.close()
    finally:
        srv.close()


def test_a_deep_link_opens_an_exercise_at_its_moment(browser, view_workdir):
    srv = shots.Server("--preset", "demo", workdir=view_workdir, paused=False)
    try:
        pg = open_page(browser, srv, "?preset=ex2&t=1500&speed=0.5")
        pg.wait_for_function("document.body.dataset.linked === '1'")
        settle(pg, srv)
        assert pg.inner_text("#title") == S.PRESETS["ex2"].title
        assert pg.inner_text("#time") == "1500" and pg.inner_text("#status") == "paused"
        assert pg.input_value("#speed") == "0.5" and pg.input_value("#preset") == "ex2"
        assert pg.inner_text("#message") == ""
        st = json.loads(srv.get("api/state"))
        assert (st["preset"], st["t_ms"], st["speed"], st["paused"]) == ("ex2", 1500, 0.5, True)
        href = pg.get_attribute("#link", "href")
        assert href == "?preset=ex2&t=1500&speed=0.5"
        # the page's own link to this moment gives the same page again
        pg.goto(srv.url + "?preset=ex2&step=3")
        pg.wait_for_function("document.body.dataset.linked === '1'")
        settle(pg, srv)
        st = json.loads(srv.get("api/state"))
        assert st["preset"] == "ex2" and st["paused"] and 0 < st["t_ms"] < 1500
        assert st["radio"]["down"] + st["radio"]["up"] >= 3
        pg.goto(srv.url + "?preset=ex99")
        pg.wait_for_function("document.body.dataset.linked === '1'")
        assert pg.inner_text("#message").startswith("the link: unknown preset 'ex99'")
        pg.close()
    finally:
        srv.close()


def follow_controls_in_the_doc():
    """The controls docs/view.md names for a follow view: the bold words of its sentence."""
    m = re.search(r"^A follow view shows (.*?)(?:\n\n)", VIEW_MD, re.M | re.S)
    assert m, "docs/view.md: no sentence 'A follow view shows ...'"
    return re.findall(r"\*\*(.+?)\*\*", m.group(1))


def live_controls_in_the_doc():
    table = VIEW_MD[VIEW_MD.index("## The controls"):]
    return " ".join(re.findall(r"^\| ([^|]+) \|", table, re.M)).lower()


def test_a_followed_trace_with_a_byte_not_utf8_goes_on_and_shows_the_line(browser, tmp_path):
    lines = NOTE.read_bytes().splitlines(keepends=True)
    path = tmp_path / "live.jsonl"
    path.write_bytes(b"".join(lines[:100]))
    srv = shots.Server("--follow", str(path), paused=False)
    try:
        pg = open_page(browser, srv)
        assert controls(pg) == follow_controls_in_the_doc() == ["Pause", "search the history"]
        with open(path, "ab") as f:
            f.write(b'{"t": 1, "ev": "radio\xff"}\n')
            f.flush()
            time.sleep(0.3)
            f.write(b"".join(lines[100:]))
        pg.wait_for_function(f"document.getElementById('radio').textContent"
                             f".includes('{len(lines)} trace lines')")
        want_rows = S.rows_of(parse(lines))
        assert want_rows[-1][2]["text"] == "answer + radio ack: block confirmed"
        settle(pg, srv)
        assert svg_texts(pg).count("write ack 16#FFFF (last) (1 reg)") == 1   # after line 101
        want = f"{path}:101:22: not UTF-8 (byte 16#FF): line skipped"
        assert pg.locator("#bad li").all_inner_texts() == [want]
        st = json.loads(srv.get("api/state"))
        assert st["lines"] == len(lines) and st["error"] is None
        pg.close()
    finally:
        srv.close()
    assert f"mip-view: {want}\n" in srv.proc.stderr.read()


@pytest.mark.slow
def test_the_live_pages_controls_are_the_docs(browser, view_workdir):
    srv = shots.Server("--preset", "clean", workdir=view_workdir)
    try:
        pg = open_page(browser, srv)
        doc = live_controls_in_the_doc()
        names = controls(pg)
        assert {"Resume", "Step scan", "speed", "search the history", "Start"} <= set(names)
        missing = [n for n in names if n.lower() not in doc]
        assert missing == [], f"controls of the page not in docs/view.md's table: {missing}"
        pg.close()
    finally:
        srv.close()
