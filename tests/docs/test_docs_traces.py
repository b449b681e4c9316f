"""The traces behind the diagrams come from st_lib itself (two soft PLCs with the runtime's
Modbus master and the emulator core in the co-simulation kernel, virtual time). Running the scenarios again must give the checked-in bytes, so the pictures
always show what the code does; and the scenarios must show what the guide says they show."""
import json

import pytest
from mipcosim.trace import read_trace

from docs_helpers import KERNEL_SO, REPO, tool

TRACES = REPO / "docs" / "traces"


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    assert KERNEL_SO.exists(), f"{KERNEL_SO} missing: run `make {KERNEL_SO.relative_to(REPO)}`"
    out = tmp_path_factory.mktemp("traces")
    r = tool("gen_traces", "-o", out)
    assert r.returncode == 0, r.stderr
    (out / "gen_traces.out").write_text(r.stdout)
    return out


NAMES = ["note-2-1-1", "bidirectional", "restart", "static-openplc", "pipelined",
         "pipelined-slow-central"]


@pytest.mark.parametrize("name", NAMES)
def test_trace_is_what_the_code_does_now(fresh, name):
    assert (fresh / f"{name}.jsonl").read_text() == (TRACES / f"{name}.jsonl").read_text(), \
        f"docs/traces/{name}.jsonl differs from a new run: run `make docs-traces docs-diagrams`"


def load(name):
    return read_trace(TRACES / f"{name}.jsonl")


def test_trace_is_ordered_and_numbered():
    for name in NAMES:
        ev = load(name)
        assert [e["seq"] for e in ev] == list(range(len(ev)))
        assert all(a["t"] <= b["t"] for a, b in zip(ev, ev[1:]))


def delivered(ev, side):
    return [e["value"] for e in ev if e["ev"] == "plc" and e["side"] == side
            and e["what"] == "deliver"]


def test_note_scenario_every_record_once_in_order_despite_the_loss():
    ev = load("note-2-1-1")
    assert delivered(ev, "central") == [1, 2, 3, 4, 65535]
    ups = [e for e in ev if e["ev"] == "radio" and e["dir"] == "up" and e["regs"]]
    first2 = next(e for e in ups if e["r0"] == 2)
    assert first2["lost"] and first2["regs"] == 123
    last = [e for e in ups if e["r0"] == 65535]
    assert last and last[-1]["regs"] == 50          # the note's 50-register last record
    # what docs/protocol.md says about this picture
    acks1 = [e for e in ev if e["ev"] == "plc" and e["side"] == "central"
             and e["what"] == "write" and e["value"] == [1]]
    assert len(acks1) >= 2, "the central does not repeat its request with acknowledgement 1"
    arrived = [e["r0"] for e in ups if not e["lost"]]
    assert len(arrived) > len(set(arrived)), "no record reaches the central twice"
    assert any(e["ev"] == "station" and e["state"] == "unreachable" for e in ev)


def test_bidirectional_both_streams_complete():
    ev = load("bidirectional")
    assert delivered(ev, "central")[-1] == 65535 and delivered(ev, "outstation")[-1] == 65535
    done = {e["side"] for e in ev if e["ev"] == "plc" and e["what"] == "done"}
    assert done == {"outstation", "central"}


def test_restart_breaks_one_transfer_and_completes_the_next():
    ev = load("restart")
    assert delivered(ev, "central") == [1, 2, 1, 2, 65535]
    errors = [e["text"] for e in ev if e["ev"] == "plc" and e["what"] == "error"]
    assert errors == ["xError: MIP_ERR_SENDER_RESET"]
    restart = next(i for i, e in enumerate(ev) if e["ev"] == "plc" and e["what"] == "restart")
    first = next(e for e in ev[restart:] if e["ev"] == "plc" and e["what"] == "write"
                 and e["side"] == "outstation")
    assert first["value"] == [1], "the restarted sender does not open with record 1 (P6)"


def test_throughput_data_reproduce():
    """Two points of docs/data/throughput-vs-loss.json, run again (seed 1, no loss and 20 %)."""
    data = json.loads((REPO / "docs" / "data" / "throughput-vs-loss.json").read_text())
    from mipdocs import gen_lossdata
    for loss in (0.0, 0.2):
        rate = gen_lossdata.run(loss, "spontaneous", 1, data["records"], data["source_key"])
        point = next(p for p in data["series"]["spontaneous"] if p["loss"] == loss)
        assert round(rate, 1) == point["regs_per_s"][0], \
            "docs/data/throughput-vs-loss.json is stale: run `make docs-lossdata docs-plot`"


def test_static_mode_only_changed_blocks_go_on_air():
    ev = load("static-openplc")
    assert delivered(ev, "central") == [1, 2, 65535]
    writes = [e for e in ev if e["ev"] == "plc" and e["side"] == "outstation"
              and e["what"] == "write"]
    changed = [w for w in writes if "unchanged" not in w["text"]]
    assert len(writes) > 2 * len(changed), "the cyclic writes are not mostly unchanged"
    ups = [e for e in ev if e["ev"] == "radio" and e["dir"] == "up" and e["regs"]]
    assert all(e["regs"] == 40 for e in ups)
    assert len(ups) == len(changed), "a radio block without a changed write, or the reverse"


def plc(ev, side, what):
    return [e for e in ev if e["ev"] == "plc" and e["side"] == side and e["what"] == what]


def first_ack_read(ev, k):
    """When the outstation first read acknowledgement k or a later one (they count
    cumulatively with window 2)."""
    return next(e["t"] for e in plc(ev, "outstation", "read") if e["value"] >= k)


def test_pipelined_records_go_up_before_the_acknowledgement_of_the_one_before():
    ev = load("pipelined")
    assert delivered(ev, "central") == [1, 2, 3, 4, 5, 65535]
    writes = plc(ev, "outstation", "write")
    assert [w["value"][0] for w in writes] == [1, 2, 3, 4, 5, 65535], "a record written twice"
    t = {w["value"][0]: w["t"] for w in writes}
    # record 2 waits for acknowledgement 1, 16#FFFF for acknowledgement 5 (P27)
    assert t[2] > first_ack_read(ev, 1) and t[65535] > first_ack_read(ev, 5)
    # 3, 4, 5 go up ahead, and their writes say so
    for n in (3, 4, 5):
        assert t[n] < first_ack_read(ev, n - 1), f"record {n} waited for ack {n - 1}"
    assert [w["text"] for w in writes if "before ack" in w["text"]] == [
        f"write record {n} (123 regs), before ack {n - 1}" for n in (3, 4, 5)]
    # a record goes up in the answer to the poll that brings the ack of the one before down
    radio = [e for e in ev if e["ev"] == "radio" and not e["lost"]]
    same = [b["r0"] for p, b in zip(radio, radio[1:]) if p["kind"] == "poll" and p["regs"]
            and b["kind"] == "answer" and b["regs"] and b["r0"] == p["r0"] + 1]
    assert same, "no record goes up in the poll that brings the ack of the one before"
    # acknowledgement 4 never goes on air: 5 replaces it in the MDP and counts for both
    down = {e["r0"] for e in radio if e["dir"] == "down" and e["regs"]}
    assert 4 in [w["value"][0] for w in plc(ev, "central", "write")] and 4 not in down
    assert not [e for e in ev if e["ev"] == "plc" and e["what"] in ("ignore", "goback", "error")]


def test_pipelined_slow_central_goes_back_once_and_then_waits():
    ev = load("pipelined-slow-central")
    assert delivered(ev, "central") == [1, 2, 3, 4, 5, 65535]
    writes = plc(ev, "outstation", "write")
    assert [w["value"][0] for w in writes] == [1, 2, 3, 4, 5, 4, 5, 65535]
    # record 5 overwrote the unread record 4 in the MDP: the central ignores it
    assert [e["text"] for e in plc(ev, "central", "ignore")] == [
        "record 5 ignored: not the next one (4)"]
    back = plc(ev, "outstation", "goback")
    assert [e["value"] for e in back] == [4]
    # ... the sender goes back tTimeout (1.5 s) after its last write, and from then on every
    # record waits for the acknowledgement of the one before (the window stays closed)
    before = [w for w in writes if w["t"] < back[0]["t"]]
    assert back[0]["t"] - before[-1]["t"] >= 1500 * 1_000_000
    after = [w for w in writes if w["t"] > back[0]["t"]]
    assert [w["value"][0] for w in after] == [4, 5, 65535]
    assert not [w for w in after if "before ack" in w["text"]]
    assert after[1]["t"] > first_ack_read(ev, 4) and after[2]["t"] > first_ack_read(ev, 5)
    assert not plc(ev, "outstation", "error") and not plc(ev, "central", "error")


def test_protocol_page_quotes_the_pipelined_times(fresh):
    """docs/protocol.md gives the xDone times of both pipelined pictures and of the same runs
    with window 1 (gen_traces runs those and prints them)."""
    import ast
    info = {}
    for line in (fresh / "gen_traces.out").read_text().splitlines():
        name, _, rest = line.removeprefix("gen_traces: ").partition(": ")
        info[name] = ast.literal_eval(rest[rest.index("{"):])
    text = (REPO / "docs" / "protocol.md").read_text()
    part = text[text.index("**Window 2"):text.index("img/seq-pipelined-slow-central.svg")]
    for name in ("pipelined", "pipelined-slow-central"):
        for key in ("done_ms", "window1_done_ms"):
            assert f"{info[name][key]} ms" in part, (name, key, info[name][key])
    ev = load("pipelined")
    assert plc(ev, "outstation", "done")[0]["t"] // 1_000_000 == info["pipelined"]["done_ms"]
