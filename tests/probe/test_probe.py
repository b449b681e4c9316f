"""mip-probe (issue 48) against the emulator over Modbus TCP: a correct network passes every
check; each wrong setting of docs/commissioning.md, produced on purpose (wrongnet.py), is named
in the first line of its station, and the other stations stay ok; the failures a field engineer
meets (unreachable, refused, a station that never answers, bad arguments) are one line each."""
import json
import re
import signal
import socket
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from miptest.emu import FAST, Emulator
from plcharness.procs import free_port
from wrongnet import FaultProxy, WritingPlc

PROBE = Path(sys.executable).parent / "mip-probe"
# quick: a short watch for PLCs and a short wait for blocks that never come
QUICK = ["--watch", "0.3", "--blocks", "3"]


def probe(*args, timeout=120):
    r = subprocess.run([str(PROBE), *map(str, args)], capture_output=True, text=True,
                       timeout=timeout)
    assert "Traceback" not in r.stdout + r.stderr, r.stdout + r.stderr
    return r


def probe_mdp(e, *args, **kw):
    """The probe of the emulator e's MDP, with args (its TRMs, options)."""
    return probe("--mdp", f"127.0.0.1:{e.mdp_port}", *args, **kw)


def probe_writing(e, plc, *args):
    """The probe of e's stations (args: its options) while plc writes to a TRM; plc stopped."""
    try:
        return probe_mdp(e, *trms(e), *args)
    finally:
        plc.stop()


def failed(r):
    """The first line of each station of a probe that found a fault (exit 1)."""
    assert r.returncode == 1
    return firsts(r.stdout)


def firsts(out):
    """station -> its first line"""
    return {int(m.group(1)): m.group(0) for m in re.finditer(r"^station (\d+): .*$", out, re.M)}


@pytest.fixture
def emu(request):
    made = []

    def start(*args):
        e = Emulator(*FAST, *args)
        made.append(e)
        return e
    yield start
    for e in made:
        assert e.stop() == 0


def trms(e, ports=None):
    out = []
    for s, p in enumerate(ports or e.trm_ports, 1):
        out += ["--trm", f"{s}=127.0.0.1:{p}"]
    return out


def test_a_correct_network_passes_every_check_and_leaves_its_evidence(emu, tmp_path):
    e = emu("--stations", 3)
    t0 = time.monotonic()
    r = probe_mdp(e, *trms(e), "--report", tmp_path / "r.json",
              "--trace", tmp_path / "t.jsonl", "--junit", tmp_path / "j.xml",
              "--st", tmp_path / "p.st", "--plcrt", tmp_path / "p.conf")
    took = time.monotonic() - t0
    assert r.returncode == 0, r.stdout + r.stderr
    assert took < 30, took
    first = firsts(r.stdout)
    assert first == {s: f"station {s}: ok: every check passed" for s in (1, 2, 3)}
    assert len(re.findall(r"^  ok   ", r.stdout, re.M)) == 3 * 10, r.stdout
    # a progress line per station
    assert len(re.findall(r"^mip-probe: station \d \(\d of 3\)", r.stderr, re.M)) == 3
    assert r.stdout.rstrip().splitlines()[-1].startswith("result: ok 3 stations")
    rep = json.loads((tmp_path / "r.json").read_text())
    assert [s["result"] for s in rep["stations"]] == ["ok"] * 3
    rt = rep["stations"][0]["round_trips"]
    assert rt["registers"] == 123 and len(rt["down"]["samples_ms"]) == 10
    assert rt["down"]["delivered_ms"]["min"] <= rt["down"]["delivered_ms"]["max"]
    # the fast radio's slots (1 ms gaps) are shorter than the probe's reads tell apart
    assert rt["down"]["slots"]["resolved"] is False and rt["down"]["slots"]["cycle_ms"] is None
    assert "its slots: faster than the probe tells apart" in r.stdout
    p = rep["recommended"]
    assert p["tTimeout_ms"] >= 2 * p["round_trip_ms"] and p["tTransferTimeout_ms"] == 5 * p["tTimeout_ms"]
    assert f"MIP_tTimeout : TIME := T#{p['tTimeout_ms']}ms;" in (tmp_path / "p.st").read_text()
    assert f"[master]\npolling_period = {p['read_period_ms']}ms\n" in (tmp_path / "p.conf").read_text()
    suite = ET.parse(tmp_path / "j.xml").getroot()
    assert suite.get("tests") == "30" and suite.get("failures") == "0"
    # the trace: mip-view --follow reads it without complaint, and it has the probe's requests
    from mipview.follow import Follow
    f = Follow(tmp_path / "t.jsonl")
    assert f.bad is None and f.events
    assert {d["ev"] for d in f.events} == {"modbus", "probe"}
    assert any(d["ev"] == "modbus" and d.get("wa") == 10 and d["st"] == 2 for d in f.events)
    # it writes only where the checklist writes: the first write registers (FC16)
    assert {(d["fc"], d["wa"]) for d in f.events if "wa" in d} == {(16, 10), (16, 2001)}
    # and leaves nothing pending: no block waiting, no new data unread, counts back to 0
    from pymodbus.client import ModbusTcpClient
    for s in (1, 2, 3):
        for port, unit, at in ((e.trm_port(s), 1, 2198), (e.mdp_port, s, 198)):
            c = ModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
            assert c.connect()
            status, count = c.read_holding_registers(at, count=2, device_id=unit).registers
            wcount = c.read_holding_registers(2000 if at == 2198 else 9, count=1,
                                              device_id=unit).registers[0]
            c.close()
            assert (status, wcount) == (0, 0), (s, at, status, wcount)
    f.station = 2
    state = f.state()                       # the page's diagram of station 2, from the probe's requests
    assert state["bad"] is None and state["svg"].startswith("<svg") and state["lines"] == len(f.events)


def test_a_static_network_passes_with_its_count(emu):
    e = emu("--stations", 1, "--mode", "static", "--static-registers", 100)
    r = probe_mdp(e, *trms(e), *QUICK)
    assert r.returncode == 0, r.stdout
    assert "static with 100 registers on both modems" in r.stdout
    assert "3 blocks of 100 registers each way" in r.stdout


def test_a_one_based_trm_is_named_and_the_others_pass(emu):
    e = emu("--stations", 3)
    px = FaultProxy(e.trm_port(2), one_based=True)
    r = probe("--mdp", f"127.0.0.1:{e.mdp_port}",
              *trms(e, [e.trm_port(1), px.port, e.trm_port(3)]), *QUICK)
    px.close()
    first = failed(r)
    assert first[2].startswith("station 2: FAIL address base: the TRM counts its register "
                               "addresses from 1"), first[2]
    assert first[1] == first[1].replace("2:", "1:") == "station 1: ok: every check passed"
    assert first[3] == "station 3: ok: every check passed"
    assert "result: FAIL 1 of 3 stations: station 2 (address base)" in r.stdout


def test_a_one_based_mdp_is_named(emu):
    e = emu("--stations", 1)
    px = FaultProxy(e.mdp_port, one_based=True)
    r = probe("--mdp", f"127.0.0.1:{px.port}", *trms(e), *QUICK)
    px.close()
    assert r.returncode == 1
    assert firsts(r.stdout)[1].startswith("station 1: FAIL address base: the MDP counts its "
                                          "register addresses from 1"), r.stdout


def test_a_static_trm_with_a_dynamic_mdp_is_named(emu):
    e = emu("--stations", 2)
    px = FaultProxy(e.trm_port(1), static=123)
    r = probe_mdp(e, *trms(e, [px.port, e.trm_port(2)]), *QUICK)
    px.close()
    first = failed(r)
    assert first[1].startswith("station 1: FAIL transfer mode: static / dynamic mismatch: the "
                               "MDP is dynamic"), first[1]
    assert "the TRM static (2000 = 123 idle, a block of 8 arrives as 123)" in first[1]
    assert first[2] == "station 2: ok: every check passed"


def test_static_counts_that_differ_are_named(emu):
    """Static modems, 100 registers at the MDP (the emulator), 123 at the TRM (the wrapper)."""
    e = emu("--stations", 1, "--mode", "static", "--static-registers", 100)
    px = FaultProxy(e.trm_port(1), static=123)
    r = probe_mdp(e, *trms(e, [px.port]), *QUICK)
    px.close()
    assert r.returncode == 1
    assert firsts(r.stdout)[1].startswith("station 1: FAIL transfer mode: static on both, but the "
                                          "counts differ: MDP 100, TRM 123"), r.stdout


def test_a_missing_station_is_named_and_the_probe_goes_on(emu):
    e = emu("--stations", 2)
    port = free_port()                      # a port nothing listens on
    r = probe_mdp(e, "--trm", f"3=127.0.0.1:{port}", *trms(e), *QUICK)
    first = failed(r)
    assert first[3].startswith("station 3: FAIL answers: the MDP has no station 3: it answers "
                               "unit id 3 with exception 0B"), first[3]
    assert f"TRM 127.0.0.1:{port}: connection refused" in first[3]
    assert first[1].endswith(": ok: every check passed") and first[2].endswith(": ok: every check passed")


def test_a_wrong_unit_id_is_named(emu):
    """The TRMs' station addresses swapped: the MDP's unit id 1 reaches the TRM given as 2."""
    e = emu("--stations", 2)
    r = probe_mdp(e, *trms(e, [e.trm_port(2), e.trm_port(1)]), *QUICK)
    first = failed(r)
    for s, other in ((1, 2), (2, 1)):
        assert first[s].startswith(f"station {s}: FAIL unit id: the block written to the MDP "
                                   f"under unit id {s} arrived at the TRM given for station "
                                   f"{other}"), first[s]


def test_a_client_that_splits_its_blocks_is_named(emu):
    """Static modems (FC6 is taken there): a PLC writing its block a register a cycle."""
    e = emu("--stations", 2, "--mode", "static", "--static-registers", 123)
    plc = WritingPlc(e.trm_port(2), split=True)
    r = probe_writing(e, plc, "--watch", "1", "--blocks", "3")
    first = failed(r)
    assert first[2].startswith("station 2: FAIL quiet: a client writes station 2's block at the "
                               "TRM in parts"), first[2]
    assert "note §1.1.3" in first[2]
    assert first[1] == "station 1: ok: every check passed"


def test_a_plc_writing_stops_the_probe_of_its_station(emu):
    e = emu("--stations", 1)
    plc = WritingPlc(e.trm_port(1), cycle=0.02)
    r = probe_writing(e, plc, "--watch", "1", "--blocks", "3")
    assert r.returncode == 1
    assert firsts(r.stdout)[1].startswith("station 1: FAIL quiet: a PLC writes to station 1: TRM ("), r.stdout
    assert "--force" in firsts(r.stdout)[1]


def test_force_probes_a_station_a_plc_writes_to(emu):
    e = emu("--stations", 1)
    plc = WritingPlc(e.trm_port(1), cycle=0.02)
    r = probe_writing(e, plc, "--watch", "0.5", "--blocks", "1", "--timeout", "1", "--force")
    assert re.search(r"^  ok   quiet         a PLC writes \(TRM \(\d+ changes in 0.5 s\)\): probing "
                     r"anyway \(--force\)$", r.stdout, re.M), r.stdout


def test_bit_4_that_never_clears_is_named(emu):
    e = emu("--stations", 1)
    px = FaultProxy(e.trm_port(1), sticky_bit4=True)
    r = probe_mdp(e, *trms(e, [px.port]), *QUICK, "--timeout", "1")
    px.close()
    assert r.returncode == 1
    assert firsts(r.stdout)[1].startswith("station 1: FAIL bit 4 up: bit 4 (write data "
                                          "unconfirmed) of the TRM's read status (2198) never "
                                          "cleared within 1 s"), r.stdout


def test_a_station_that_never_answers_on_the_radio(emu):
    e = emu("--stations", 1, "--loss-down", 1, "--loss-up", 1)
    r = probe_mdp(e, *trms(e), *QUICK, "--timeout", "0.5")
    assert r.returncode == 1
    assert firsts(r.stdout)[1].startswith("station 1: FAIL block down: a block written to the "
                                          "MDP for station 1 never arrived at the TRM"), r.stdout
    assert "the MDP never heard station 1 (field strengths register 0 = 0" in r.stdout


@pytest.mark.parametrize("args, want", [
    (["--mdp", "127.0.0.1:0x", "--trm", "1=127.0.0.1:502"], "mip-probe: error: 127.0.0.1:0x: HOST[:PORT]"),
    (["--mdp", "127.0.0.1", "--trm", "1"], "mip-probe: error: --trm 1: S=ENDPOINT with a station 1..247"),
    (["--mdp", "127.0.0.1", "--trm", "1=rtu:"], "mip-probe: error: rtu:: rtu:DEVICE"),
    (["--mdp", "127.0.0.1", "--trm", "1=a", "--registers", "124"], "mip-probe: error: --registers 124: at most 123"),
    (["--trm", "1=a"], "mip-probe: error: the following arguments are required: --mdp"),
])
def test_bad_arguments_are_one_line(args, want):
    r = probe(*args)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and r.stderr.startswith(want), r.stderr


def test_unreachable_and_silent_are_one_line_each_and_the_probe_goes_on(emu, tmp_path):
    e = emu("--stations", 1)
    silent = socket.socket()                # takes the connection, never answers
    silent.bind(("127.0.0.1", 0))
    silent.listen(4)
    port = silent.getsockname()[1]
    # 192.0.2.1: TEST-NET-1 (RFC 5737), routed nowhere (refused or unanswered, by the network)
    r = probe_mdp(e, "--trm", f"2=127.0.0.1:{port}",
              "--trm", "3=192.0.2.1:502", *trms(e), *QUICK,
              "--request-timeout", "0.3", "--report", tmp_path / "no" / "r.json")
    silent.close()
    first = firsts(r.stdout)
    assert first[1] == "station 1: ok: every check passed"
    assert first[2].startswith("station 2: FAIL answers: the MDP has no station 2"), first[2]
    assert f"TRM 127.0.0.1:{port}: no answer to read of 1 at 2000 within 0.3 s" in first[2], first[2]
    assert re.search(r"; TRM 192\.0\.2\.1:502: (connection refused|no answer to the connection "
                     r"within 0\.3 s|Network is unreachable|No route to host)", first[3]), first[3]
    # the report's directory does not exist: one line, exit 2
    assert r.returncode == 2 and r.stderr.splitlines()[-1] == \
        f"mip-probe: error: {tmp_path / 'no' / 'r.json'}: No such file or directory"


def test_ctrl_c_writes_what_it_has(emu, tmp_path):
    # Ctrl-C comes while station 2 is watched for PLCs (a second after its first check)
    e = Emulator(*FAST, "--stations", 2)
    try:
        p = subprocess.Popen([str(PROBE), "--mdp", f"127.0.0.1:{e.mdp_port}", *trms(e),
                              "--watch", "1", "--blocks", "2", "--report", tmp_path / "r.json",
                              "--trace", tmp_path / "t.jsonl"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            # station 2's first check result (station 1 reads station 2's TRM too)
            if (tmp_path / "t.jsonl").exists() and \
                    '"ev": "probe", "st": 2' in (tmp_path / "t.jsonl").read_text():
                break
            time.sleep(0.05)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=30)
    finally:
        assert e.stop() == 0
    assert "Traceback" not in out + err, out + err
    assert p.returncode == 130, out + err
    assert firsts(out)[1] == "station 1: ok: every check passed"
    assert "station 2: INTERRUPTED (Ctrl-C) during the checks" in out
    assert out.rstrip().splitlines()[-1].startswith("result: INTERRUPTED after 2 of 2 stations; wrote")
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["interrupted"] and [s["result"] for s in rep["stations"]] == ["ok", "interrupted"]


def test_a_second_run_takes_the_first_runs_blocks_for_nothing(emu):
    """The read areas keep the last blocks; a run looks for its own (its nonce), so a second
    probe of the same network is ok again (it once called them damaged)."""
    e = emu("--stations", 1)
    for _ in range(2):
        r = probe_mdp(e, *trms(e), *QUICK)
        assert r.returncode == 0 and firsts(r.stdout) == {1: "station 1: ok: every check passed"}, r.stdout


@pytest.mark.slow
def test_three_stations_on_the_realistic_radio_within_three_minutes(tmp_path):
    """Full tier (about 1.5 minutes): the default 9600 bit/s radio, 20 ms gaps, the defaults of
    the probe (2 s watch, 10 blocks of 123 registers per station and direction)."""
    e = Emulator("--stations", 3)
    try:
        t0 = time.monotonic()
        r = probe_mdp(e, *trms(e), "--report", tmp_path / "r.json",
                  timeout=400)
        took = time.monotonic() - t0
    finally:
        assert e.stop() == 0
    assert r.returncode == 0, r.stdout + r.stderr
    assert took < 180, took
    assert firsts(r.stdout) == {s: f"station {s}: ok: every check passed" for s in (1, 2, 3)}
    rep = json.loads((tmp_path / "r.json").read_text())
    p = rep["recommended"]
    # the station's cycle (emulator/README.md "Radio model"): its slot with a block down (215
    # + 20 + 10 + 20 ms) or up and its ack (10 + 20 + 215 + 20 + 10 + 20 ms), and the two
    # other stations' empty slots (60 ms each)
    for st in rep["stations"]:
        for d, want in (("down", 385), ("up", 415)):
            s = st["round_trips"][d]["slots"]
            assert s["resolved"] and abs(s["cycle_ms"] - want) <= 25, (st["station"], d, s)
    # a 123-register block each way plus the ack: 500 ms a slot (emulator/README.md); the
    # deliveries of three stations' blocks take up to a poll cycle or two
    assert 250 <= p["poll_cycle_ms"] <= 3000, p
    assert p["tTimeout_ms"] >= 2 * p["round_trip_ms"], p


def test_blocks_0_checks_without_measuring(emu, tmp_path):
    e = emu("--stations", 1)
    r = probe_mdp(e, *trms(e), "--watch", "0.2", "--blocks", "0",
              "--junit", tmp_path / "j.xml", "--st", tmp_path / "p.st")
    assert r.returncode == 0, r.stdout
    assert "  -    round trips   not measured (--blocks 0)" in r.stdout
    assert "recommended" not in r.stdout and not (tmp_path / "p.st").exists()
    suite = ET.parse(tmp_path / "j.xml").getroot()
    assert (suite.get("failures"), suite.get("skipped")) == ("0", "1")
