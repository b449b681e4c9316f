"""The whole chain in the test kit (issue 35 item 9): relay -> outstation -> radio -> central ->
WinCC OA, with programs an integrator writes. The example project's chain (kit/example/:
st/RelayStation.st, st/WinccCentral.st, scenarios/chain.toml) through mip-kit; its
tests/test_chain.py runs through the pytest plugin with the example's other tests
(test_kit_quick.py, test_passing_run_leaves_only_the_junit_files_in_results). And the
project's own push central (plc/central_push.st, MIP_UnicosEvents) with its outstation
(plc/outstation_soe.st) as an integrator's programs in a scenario file."""
import json
import re

import pytest

import kit_helpers
from mipkit.scenario import main


def kit(capsys, scenario, work):
    rc = main([str(scenario), "--workdir", str(work), "--results", str(work / "results")])
    return rc, capsys.readouterr().out


def page_block():
    """docs/test-kit.md's console block of the example's chain scenario: its expected lines."""
    page = (kit_helpers.REPO / "docs" / "test-kit.md").read_text()
    blocks = [b for b in re.findall(r"```console\n(.*?)```", page, re.S)
              if "kit/example/scenarios/chain.toml" in b]
    assert len(blocks) == 1, "docs/test-kit.md: the chain scenario's block is gone"
    lines = blocks[0].splitlines()
    i = next(k for k, l in enumerate(lines) if l.startswith("$ "))
    return lines[i + 1:]


def same(line):
    """A line without what depends on the blocks' timing rather than on the example (the wall
    time, the radio's telegram counts, the writes the driver left unanswered): a change of
    st_lib's timing does not make the page wrong, a lost or repeated event does."""
    for pat, rep in ((r"\d+(\.\d+)? s wall", "TIME s wall"),
                     (r"radio lost \d+ of \d+ telegrams down, \d+ of \d+ up", "radio lost N"),
                     (r"\b\d+ unanswered", "N unanswered")):
        line = re.sub(pat, rep, line)
    return line


def test_the_examples_chain_scenario(capsys, example, tmp_path):
    """scenarios/chain.toml: every relay event reaches WinCC OA once although the driver is away
    for 3 s and the outstation is killed; what it prints is what docs/test-kit.md shows. With
    the driver away for the whole run the same scenario fails naming the first event that did
    not arrive."""
    f = example / "scenarios" / "chain.toml"
    rc, out = kit(capsys, f, tmp_path / "work")
    assert rc == 0, out
    assert [same(l) for l in out.splitlines() if not l.startswith("plcrt:")] == \
        [same(l) for l in page_block()], out
    assert re.search(r"unicos wincc: driver A: 12 events, 0 duplicates, 0 refused, [1-9]\d* "
                     r"unanswered", out), out           # the central wrote in vain while it was away
    text = f.read_text()
    assert text.count("down = [[2.0, 5.0]]") == 1
    f.write_text(text.replace("down = [[2.0, 5.0]]", "down = [[0.0, 30.0]]"))
    rc, out = kit(capsys, f, tmp_path / "work")
    assert rc == 1, out
    # the first scripted event: type/bit, address, cause/type, value, its time stamp (500 ms)
    first = [0x0102, 200, 0x0101, 1, 0, 411, 30426, 43008 + 500]
    line = (f"FAIL every event of relay reached wincc: 12 of 12 events of relay did not reach "
            f"wincc; the first: {first}")
    assert line in out, out
    page = " ".join((kit_helpers.REPO / "docs" / "test-kit.md").read_text().split())
    assert f"`{line}`" in page                   # the page quotes it
    assert "FAIL events at WinCC OA" in out and "Traceback" not in out


@pytest.mark.slow
def test_the_push_central_hands_every_relay_event_to_wincc_once(capsys, tmp_path):
    """plc/central_push.st (MIP_Receiver with xAckByCaller, MIP_UnicosEvents) and
    plc/outstation_soe.st, unchanged, as an integrator's programs in a scenario file: 40 relay
    events over the realistic radio with 10 % loss each way to a redundant pair of UNICOS
    drivers whose driver A (the active one) is away from 2 s to 4 s; both drivers take every
    event once, with the relay's time stamp. Slow: a cold build cache builds both programs
    (about 10 s); under a second when cached."""
    from mipcosim import chainprograms as C
    d = tmp_path / "scenario"
    d.mkdir()
    (d / "central_push.conf").write_text(C.central_push_config())
    words = C.SoeParams(redundant=True).words()
    params = "{ " + ", ".join(f'"%MW{i}" = {w}' for i, w in enumerate(words)) + " }"
    events = C.script(40, start_s=0.5, every_s=0.1)
    (d / "push.toml").write_text(f"""name = "chain-push"
[network]
radio = "realistic"
loss_down = 0.1
loss_up = 0.1
seed = 3
[[plc]]
name = "outstation"
sources = {json.dumps(C.program_sources("out"))}
config = {json.dumps(str(C.L.PLC_DIR / "outstation_soe.conf"))}
station = 1
set = {params}
[[plc]]
name = "central"
sources = {json.dumps(C.program_sources("cen", "push"))}
config = "central_push.conf"
station = "mdp"
set = {params}
[[relay]]
name = "relay"
plc = "outstation"
device = "relay"
origin_ms = {C.ORIGIN_MS}
events = {json.dumps([[t] + w for t, w in events])}
[[unicos]]
name = "wincc"
plc = "central"
device = "unicos_a"
device_b = "unicos_b"
marker = {C.UNICOS_MARKER}
down = [[2.0, 4.0]]
[expect]
run_s = 40
reached = [{{ relay = "relay", at = "wincc" }}]
no_duplicates = ["wincc"]
values = [{{ at = "wincc", equals = 40 }}, {{ at = "central:%MW{C.PUSH_EVENTS},%MW{C.PUSH_EVENTS + 1}", equals = 40 }}]
""")
    rc, out = kit(capsys, d / "push.toml", tmp_path / "work")
    assert rc == 0, out
    assert "ok   every event of relay reached wincc" in out, out
    m = re.search(r"driver A: 40 events, 0 duplicates, 0 refused, (\d+) unanswered; "
                  r"driver B: 40 events, 0 duplicates", out)
    assert m and int(m.group(1)) > 0, out        # A was away: the central wrote to it in vain
    assert "40 acknowledged, 0 dropped (overflow), 0 still in the recorder" in out, out


@pytest.mark.slow
def test_matiec_builds_the_examples_chain_when_iec2c_is_on_path(capsys, example, tmp_path):
    """The example's chain scenario with the reference compiler (iec2c on PATH): its programs
    stay inside what matiec accepts. Slow: matiec's builds of both programs take about 20 s."""
    from plcharness.build import matiec_available
    if not matiec_available():
        pytest.skip("matiec (iec2c) is not on PATH; it is in no package registry")
    rc = main([str(example / "scenarios" / "chain.toml"), "--compiler", "matiec",
               "--workdir", str(tmp_path / "work")])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "ok   every event of relay reached wincc" in out and "ok   no duplicates at wincc" in out
