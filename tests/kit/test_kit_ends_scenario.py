"""The chain's ends in the scenario file ([[relay]], [[unicos]], [[scada]], expect.reached,
expect.no_duplicates; docs/test-kit.md): mip-kit in process on the scenarios of tests/kit/ends/,
one shared work directory so the programs are built once."""
import re
import shutil

import pytest

import kit_helpers
from mipkit.scenario import main

from test_kit_ends import HERE


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("ends-work")


def kit(capsys, work, scenario, *more):
    rc = main([str(scenario), "--workdir", str(work), "--results", str(work / "results"), *more])
    return rc, capsys.readouterr().out


def variant(tmp_path, name, change):
    """A copy of tests/kit/ends/NAME.toml (next to the programs it names) changed by change()."""
    d = tmp_path / "ends"
    if not d.exists():
        shutil.copytree(HERE, d)
    f = d / f"{name}.toml"
    f.write_text(change(f.read_text()))
    return f


def test_relay_events_reached_the_outstations_log(capsys, work, tmp_path):
    rc, out = kit(capsys, work, HERE / "relay.toml")
    assert rc == 0, out
    assert "ok   every event of relay reached outstation:MAIN.aLog[0..63]" in out
    assert "relay relay: 4 events (4 scripted), 4 acknowledged, 0 dropped (overflow)" in out
    # an event after the end of the run did not reach it: named, with its registers
    f = variant(tmp_path, "relay", lambda t: t.replace("[1.2, 0x0102, 101, 0x0101, 0]",
                                                       "[2.5, 0x0102, 101, 0x0101, 0]"))
    rc, out = kit(capsys, work, f)
    assert rc == 1, out
    assert ("FAIL every event of relay reached outstation:MAIN.aLog[0..63]: 1 of 4 events of "
            "relay did not reach outstation:MAIN.aLog[0..63]; the first: [258, 101, 257, 0, 0, "
            "411, 30426, 45508]") in out, out


def test_pull_and_push_with_their_stand_ins_down_for_a_while(capsys, work):
    rc, out = kit(capsys, work, HERE / "pull.toml")
    assert rc == 0, out
    assert "ok   no duplicates at scada" in out
    assert re.search(r"scada scada: 12 entries, 0 duplicates, 4 acknowledgements", out), out
    rc, out = kit(capsys, work, HERE / "push.toml")
    assert rc == 0, out
    assert "unicos wincc: driver A: 2 events, 0 duplicates, 0 refused" in out, out
    assert "driver B: 2 events, 0 duplicates" in out, out


@pytest.mark.parametrize("name, change, line", [
    ("relay", lambda t: t.replace('device = "relay"', 'device = "relay"\nspeed = 3'),
     r"unknown key 'relay.speed' \(known in \[relay\]: bad_ack, base, burst, capacity, "),
    ("relay", lambda t: t.replace('plc = "outstation"\n', ""),
     r"FAIL scenario runs: \[\[relay\]\] relay: 'plc' missing \(the PLC that reads it\)$"),
    ("relay", lambda t: t.replace('device = "relay"', 'device = "relay"\nburst = [3]'),
     r"FAIL scenario runs: relay.burst = \[3\]: \[n, every_s\], both > 0$"),
    ("relay", lambda t: t.replace('[0.5, 0x0105', '[0.5, 0x10105'),
     r"FAIL scenario runs: relay relay: event \[65797, 17, 257, 1\]: four words"),
    ("relay", lambda t: t.replace('at = "outstation:MAIN.aLog[0..63]"', 'at = "wincc"'),
     r"FAIL scenario runs: expect.reached at = 'wincc': no PLC or peer named 'wincc'"),
    ("push", lambda t: t.replace("down = [[0.0, 1.0]]", "down = [[1.0, 0.5]]"),
     r"FAIL scenario runs: unicos wincc: down = \[1\.0, 0\.5\]: a pair \[from_s, to_s\]"),
    ("push", lambda t: t.replace('device_b = "unicos_b"', 'device_b = "unicos_c"'),
     r"FAIL scenario runs: central: device 'unicos_c' is not in .*unicos\.conf \(it has unicos, "
     r"unicos_b\)$"),
    ("pull", lambda t: t.replace('no_duplicates = ["scada"]', 'no_duplicates = ["central"]'),
     r"FAIL scenario runs: expect.no_duplicates: 'central': a \[\[unicos\]\] or \[\[scada\]\] name$"),
])
def test_bad_ends_are_one_line(capsys, work, tmp_path, name, change, line):
    rc, out = kit(capsys, work, variant(tmp_path, name, change))
    assert rc == 1, out
    fails = [l for l in out.splitlines() if l.startswith("FAIL")]
    assert len(fails) == 1 and re.search(line, fails[0]), out
    assert "Traceback" not in out


def test_the_pages_ends_tables_use_known_keys():
    """docs/test-kit.md's [[relay]] / [[unicos]] / [[scada]] example: every key is one mip-kit
    knows (a renamed key would make the page's example a one-line error)."""
    import tomllib
    from mipkit.scenario import _check_keys
    page = (kit_helpers.REPO / "docs" / "test-kit.md").read_text()
    block = next(b for b in re.findall(r"```toml\n(.*?)```", page, re.S) if "[[relay]]" in b)
    doc = tomllib.loads(block)
    _check_keys(doc, "", "test-kit.md")
    for t in ("relay", "unicos", "scada"):
        assert doc[t], t
        for item in doc[t]:
            _check_keys(item, t, "test-kit.md")
    for v in doc["expect"]["reached"]:
        _check_keys(v, "expect.reached", "test-kit.md")
    _check_keys(doc["expect"], "expect", "test-kit.md")
