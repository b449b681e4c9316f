"""The whole chain in the view (view/mipview/chainview.py): the relay's reads and
acknowledgements and the SCADA's polls beside the radio hop, live (the co-simulated chain) and
followed (the real-time chain demo's run directory), and in the page (Chromium)."""
from __future__ import annotations

import json
import time

import pytest

from view_helpers import needs_browser
from mipview import shots
from mipview import session as S
from mipview.chainview import ChainLive, merged

RELAY_READ = "relay -> PLC: FC3 40601.., 1 entry read, stored in the logger (RETAIN)"
RELAY_ACK = "PLC -> relay: FC16 SOE_Control, 1 entry acknowledged, deleted at the relay"


def run_chain(workdir, limit_ms=20_000):
    s = ChainLive(workdir)
    while not s.done and s.t_ms < limit_ms:
        s.step()
    assert s.done, "the chain did not bring every event to the SCADA"
    return s


def test_the_live_chain_shows_both_ends_and_the_records(view_workdir):
    s = run_chain(view_workdir)
    try:
        texts = [d["text"] for _, _, d in S.rows_of(s.lines)]
        taken = [r["value"] for r in s.ch.rows]
        st = s.state()
    finally:
        s.close()
    assert taken == list(range(20))                          # every event at the SCADA once
    assert texts.count("relay: 1 event recorded (1 in its recorder)") >= 1
    assert texts.count(RELAY_READ) >= 10 and texts.count(RELAY_ACK) >= 10
    scada = [t for t in texts if t.startswith("SCADA <- central: FC3 40601.., took ")]
    assert scada and sum(int(t.split("took ")[1].split(" ")[0]) for t in scada) == 20
    assert any(t.startswith("SCADA -> central: FC6 SOE_Control") for t in texts)
    assert any(t.startswith("write record 1 (") for t in texts)
    assert "write record 16#FFFF (last) (1 reg)" in texts
    assert not any(t.startswith("FC16 write") or "[0]=" in t for t in texts)
    blocks = {b["side"]: {v["name"]: v["value"] for v in b["vars"]} for b in st["blocks"]}
    assert blocks["relay"]["entries in the recorder"] == 0
    assert blocks["scada"]["entries taken"] == 20


def test_a_followed_chain_demo_run_shows_the_relay_and_the_scada(view_workdir, tmp_path):
    """A run directory as plc/demo.py --chain (mipdemo.chain) leaves it: the emulator's trace (no PLC lines),
    the relay's script events.txt and the SCADA's scada-entries.jsonl."""
    s = run_chain(view_workdir)
    try:
        emu = [d for d in s.lines if d["ev"] != "plc"]
        script = s.ch.s.events
        rows = list(s.ch.rows)
    finally:
        s.close()
    (tmp_path / "emulator-trace.jsonl").write_text("".join(json.dumps(d) + "\n" for d in emu))
    (tmp_path / "events.txt").write_text("".join(
        f"{t:.3f} " + " ".join(f"{w:#06x}" for w in ws) + "\n" for t, ws in script))
    (tmp_path / "scada-entries.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    f = S.Follow(tmp_path / "emulator-trace.jsonl")
    texts = [d["text"] for _, _, d in S.rows_of(merged(f.events, f.ends))]
    assert [t for t in texts if t.startswith("relay: event recorded")] == [
        f"relay: event recorded (value {w[3]})" for _, w in script]
    assert texts[-1] == ("SCADA took 20 entries (values " + ", ".join(map(str, range(20)))
                         + "), seen by the view at this time")
    assert any(t.startswith("write record 1 (") for t in texts)
    assert not any(t.startswith("FC16 write") for t in texts)


@needs_browser
def test_the_chain_in_the_page_with_its_relay_and_control_system_ends(browser, view_workdir):
    srv = shots.Server("--preset", "clean", workdir=view_workdir)
    try:
        pg = browser.new_page(viewport=shots.VIEWPORT)
        pg.goto(srv.url + "?preset=chain&t=2000")
        pg.wait_for_function("document.body.dataset.linked === '1'")
        pg.wait_for_function("(document.body.dataset.pending || '0') === '0'")
        assert pg.inner_text("#message") == ""
        texts = pg.locator("#diagram svg text").all_text_contents()
        assert RELAY_READ in texts and RELAY_ACK in texts
        assert any(t.startswith("SCADA <- central: FC3 40601.., took ") for t in texts)
        assert any(t.startswith("write record 1 (") for t in texts)
        assert not any(t.startswith("FC16 write") for t in texts)
        heads = pg.locator("#blocks th").all_inner_texts()
        assert heads[0].startswith("relay: ") and heads[-1].startswith("control system: ")
        assert pg.locator("#lose-record").is_hidden()            # no faults of the page's own
        assert pg.get_attribute("#registers td[data-addr='10']", "title").startswith(
            "acknowledgement counter")                           # the modems' windows too
        assert pg.locator("#step-slot").is_visible()
        pg.close()
    finally:
        srv.close()


def test_the_push_chain_shows_the_hand_over_to_wincc_oa(view_workdir):
    s = ChainLive(view_workdir, handover="push")
    try:
        while not s.done and s.t_ms < 20_000:
            s.step()
        assert s.done
        texts = [d["text"] for _, _, d in S.rows_of(s.lines)]
        st = s.state()
    finally:
        s.close()
    for drv in "AB":                 # the redundant pair: every event to both drivers
        pushed = [t for t in texts
                  if t.startswith(f"central -> WinCC OA (UNICOS driver {drv}): events pushed")]
        vals = [int(v) for t in pushed for v in t.split("(values ")[1].rstrip(")").split(", ")]
        assert vals == list(range(20)), drv
    assert RELAY_READ in texts and not any(t.startswith("SCADA") for t in texts)
    assert st["blocks"][-1]["head"] == "control system" and "WinCC OA" in st["blocks"][-1]["block"]


@pytest.mark.slow
def test_the_real_time_chain_demo_followed_with_its_ends():
    """--demo "--chain": plc/demo.py --chain (mipdemo.chain) in real time (mip-emulator with a relay, two soft
    PLCs, mip-peer scada); the page's rows have the relay's events and the SCADA's takes
    beside the records, and the demo's own result line (not the last run's)."""
    srv = shots.Server("--demo", "--chain --events 10", paused=False)
    try:
        deadline = time.time() + 120
        st = json.loads(srv.get("api/state"))
        while time.time() < deadline and not (st.get("note") or "").startswith("result:"):
            time.sleep(0.3)
            st = json.loads(srv.get("api/state"))
        assert (st["note"] or "").startswith("result: ok events=10 "), st["note"]
        time.sleep(0.5)                         # the SCADA's last entries read by the view
        texts = [r["text"] for r in json.loads(srv.get("api/state"))["rows"]]
    finally:
        srv.close()
    assert len([t for t in texts if t.startswith("relay: event recorded")]) == 10
    took = [t for t in texts if t.startswith("SCADA took ")]
    assert sum(int(t.split()[2]) for t in took) == 10
    assert any(t.startswith("write record 1 (") for t in texts)
    assert not any(t.startswith("FC16 write") for t in texts)
