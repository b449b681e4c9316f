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
from mipcosim.kernel import MS

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


ORIGIN = 7_000_000_000          # CLOCK_MONOTONIC at the trace's time 0 (the emulator's start)


def test_a_followed_run_directory_draws_the_relays_handshake_and_the_scadas_takes_in_time(
        tmp_path):
    """A small run directory as the real-time demo writes it: mip-emulator --relay --trace's
    "relay" lines (its clock's origin, a read, an acknowledgement, a refused one), the relay's
    script, the SCADA's entries with the times it took them (mono_ns), and one older entry
    without a time."""
    trace = [
        {"t": 0, "seq": 0, "ev": "relay", "start": True, "mono_ns": ORIGIN},
        {"t": 100 * MS, "seq": 1, "ev": "relay", "fc": 3, "ra": 600, "rq": 26, "soe": 0x0201,
         "offered": 2, "entries": 2},
        {"t": 110 * MS, "seq": 2, "ev": "relay", "fc": 16, "wa": 601, "w0": 0x0201, "exc": 0,
         "acked": 2, "entries": 0},
        {"t": 120 * MS, "seq": 3, "ev": "relay", "fc": 16, "wa": 601, "w0": 0x0201, "exc": 3,
         "acked": 0, "entries": 0},
        {"t": 900 * MS, "seq": 4, "ev": "station", "st": 1, "state": "reachable"},
    ]
    (tmp_path / "emulator-trace.jsonl").write_text("".join(json.dumps(d) + "\n" for d in trace))
    (tmp_path / "events.txt").write_text("0.050 0x0102 101 0x0101 7\n0.060 0x0102 102 0x0101 8\n")
    (tmp_path / "scada-entries.jsonl").write_text(
        json.dumps({"value": 7, "mono_ns": ORIGIN + 800 * MS}) + "\n"
        + json.dumps({"value": 8, "mono_ns": ORIGIN + 800 * MS}) + "\n"
        + json.dumps({"value": 9}) + "\n")
    f = S.Follow(tmp_path / "emulator-trace.jsonl")
    got = [(t // MS, d["text"]) for t, _, d in S.rows_of(merged(f.events, f.ends))
           if d.get("side") in ("outstation", "central")]
    assert got == [
        (50, "relay: event recorded (value 7)"),
        (60, "relay: event recorded (value 8)"),
        (100, "relay -> PLC: FC3 40601.., 2 entries offered (SOE_Control 16#0201, 2 in its "
              "recorder)"),
        (110, "PLC -> relay: FC16 SOE_Control, 2 entries acknowledged, deleted at the relay "
              "(0 left)"),
        (120, "PLC -> relay: FC16 SOE_Control 16#0201 refused (exception 03)"),
        (800, "SCADA <- central: FC3 40601.., took 2 entries (values 7, 8)"),
        (900, "SCADA took 1 entry (values 9), seen by the view at this time"),
    ]


def test_a_followed_push_run_draws_the_pushes_to_drivers_a_and_b_in_time(tmp_path):
    """The push variant's run directory: WinCC OA's drivers' file (unicos-events.jsonl, each
    event with its driver and mono_ns) instead of the SCADA's; a status table is no event."""
    trace = [{"t": 0, "seq": 0, "ev": "relay", "start": True, "mono_ns": ORIGIN},
             {"t": 900 * MS, "seq": 1, "ev": "station", "st": 1, "state": "reachable"}]
    (tmp_path / "emulator-trace.jsonl").write_text("".join(json.dumps(d) + "\n" for d in trace))
    (tmp_path / "events.txt").write_text("0.050 0x0102 101 0x0101 7\n")

    def ev(drv, value, at_ms):
        return json.dumps({"kind": "event", "driver": drv, "sub": 0x11, "offset": 101,
                           "value": 0x0102 << 16 | value, "mono_ns": ORIGIN + at_ms * MS}) + "\n"
    (tmp_path / "unicos-events.jsonl").write_text(
        ev("A", 7, 600) + ev("A", 8, 600) + ev("B", 7, 610) + ev("B", 8, 610)
        + json.dumps({"kind": "status", "driver": "A", "offset": 0, "words": [],
                      "mono_ns": ORIGIN + 620 * MS}) + "\n")
    f = S.Follow(tmp_path / "emulator-trace.jsonl")
    got = [(t // MS, d["text"]) for t, _, d in S.rows_of(merged(f.events, f.ends))
           if d.get("side") == "central"]
    assert got == [
        (600, "central -> WinCC OA (UNICOS driver A): events pushed and answered (values 7, 8)"),
        (610, "central -> WinCC OA (UNICOS driver B): events pushed and answered (values 7, 8)"),
    ]


def test_a_new_run_in_the_followed_directory_drops_the_last_runs_ends(tmp_path):
    """The demo starts over in the same directory (the trace truncated): the page shows the
    new run's relay and SCADA, none of the old run's entries."""
    def run(value, n_lines):
        trace = [{"t": 0, "seq": 0, "ev": "relay", "start": True, "mono_ns": ORIGIN}] + [
            {"t": (k + 1) * 100 * MS, "seq": k + 1, "ev": "station", "st": 1,
             "state": "reachable"} for k in range(n_lines)]
        (tmp_path / "emulator-trace.jsonl").write_text(
            "".join(json.dumps(d) + "\n" for d in trace))
        (tmp_path / "events.txt").write_text(f"0.050 0x0102 101 0x0101 {value}\n")
        (tmp_path / "scada-entries.jsonl").write_text(
            json.dumps({"value": value, "mono_ns": ORIGIN + 80 * MS}) + "\n")
    run(7, 9)
    f = S.Follow(tmp_path / "emulator-trace.jsonl")
    run(8, 2)                                    # shorter: the view sees the truncation
    f.poll()
    f.poll()                                     # the new run's files, once it has lines
    got = [d["text"] for _, _, d in S.rows_of(merged(f.events, f.ends))
           if d.get("side") in ("outstation", "central")]
    assert got == ["relay: event recorded (value 8)",
                   "SCADA <- central: FC3 40601.., took 1 entry (values 8)"]


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


def follow_the_demo(args):
    """The page's whole history of `--demo ARGS` once the demo printed its result (its state
    inlines the last chunk's rows only: the same files are read again as the page reads them;
    the demo's last lines may have come after the page's last state)."""
    srv = shots.Server("--demo", args, paused=False)
    try:
        deadline = time.time() + 120
        st = json.loads(srv.get("api/state"))
        while time.time() < deadline and not (st.get("note") or "").startswith("result:"):
            time.sleep(0.3)
            st = json.loads(srv.get("api/state"))
        assert (st["note"] or "").startswith("result: ok events=10 "), st["note"]
        time.sleep(0.5)                         # the control system's last entries read
        st = json.loads(srv.get("api/state"))
    finally:
        srv.close()
    f = S.Follow(st["title"])
    texts = [d["text"] for _, _, d in S.rows_of(merged(f.events, f.ends))]
    assert len(texts) >= st["nrows"] > 0     # nothing of an earlier run in the page
    assert len([t for t in texts if t.startswith("relay: event recorded")]) == 10
    assert any(t.startswith("relay -> PLC: FC3 40601.., ") for t in texts)
    acked = [t.split(", ")[1].split()[0] for t in texts
             if t.startswith("PLC -> relay: FC") and " acknowledged" in t]
    assert sum(int(n) for n in acked) == 10                  # the relay's recorder emptied
    assert any(t.startswith("write record 1 (") for t in texts)
    assert not any(t.startswith("FC16 write") for t in texts)
    return texts


@pytest.mark.slow
def test_the_real_time_chain_demo_followed_with_its_ends():
    """--demo "--chain": plc/demo.py --chain (mipdemo.chain) in real time (mip-emulator with a relay, two soft
    PLCs, mip-peer scada); the page's rows have the relay's events, reads and
    acknowledgements and the SCADA's takes (each at the time it took them) beside the records,
    and the demo's own result line (not the last run's)."""
    texts = follow_the_demo("--chain --events 10")
    took = [t for t in texts if t.startswith("SCADA <- central: FC3 40601.., took ")]
    assert sum(int(t.split()[6]) for t in took) == 10


@pytest.mark.slow
def test_the_real_time_push_chain_demo_followed_with_both_drivers():
    """--demo "--chain --handover push": the pushes to WinCC OA's drivers A and B, each at
    the time the driver took it, every event to both."""
    texts = follow_the_demo("--chain --handover push --events 10")
    for drv in "AB":
        pushed = [t for t in texts
                  if t.startswith(f"central -> WinCC OA (UNICOS driver {drv}): events pushed")]
        vals = [int(v) for t in pushed for v in t.split("(values ")[1].rstrip(")").split(", ")]
        assert vals == list(range(10)), drv
    assert not any(t.startswith("SCADA") for t in texts)
