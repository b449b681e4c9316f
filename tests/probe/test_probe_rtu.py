"""mip-probe over Modbus RTU (the emulator's RTU slaves on ptys, one line per modem): a correct
station passes every check, and the line's time is added to tTimeout as docs/serial.md says;
a station the MDP does not have is silent on RTU, and the first line says what that means.

Each wrong setting of docs/commissioning.md, "Symptoms of each wrong setting", produced over RTU
as test_probe.py produces it over TCP: the same wrong modems (wrongnet.Faults) behind a serial
front (wrongnet.FaultLine: the probe's port and a PLC's, on the emulator's line), the first line
of the station named as the TCP tests assert it."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

from miptest.emu import FAST, Emulator
from wrongnet import FaultLine, WritingPlc

PROBE = Path(sys.executable).parent / "mip-probe"
# a pty takes only 8N1 from pymodbus (docs/serial.md, parity on a pty)
LINE = "115200:8N1"


def test_rtu_station_passes_and_a_missing_one_is_named(tmp_path):
    e = Emulator(*FAST, "--stations", 1, "--rtu", f"pty:{tmp_path}/mdp:115200=mdp",
                 "--rtu", f"pty:{tmp_path}/trm:115200=trm1@1")
    try:
        r = subprocess.run([str(PROBE), "--mdp", f"rtu:{tmp_path}/mdp:{LINE}",
                            "--trm", f"1=rtu:{tmp_path}/trm:{LINE}@1",
                            "--trm", f"2=rtu:{tmp_path}/trm:{LINE}@2",
                            "--watch", "0.3", "--blocks", "3", "--request-timeout", "0.3"],
                           capture_output=True, text=True, timeout=120)
    finally:
        assert e.stop() == 0
    out = r.stdout
    assert "Traceback" not in out + r.stderr
    assert r.returncode == 1, out + r.stderr
    assert re.search(r"^station 1: ok: every check passed$", out, re.M), out
    m = re.search(r"^station 2: FAIL answers: (.*)$", out, re.M)
    assert m and m.group(1).startswith(f"MDP rtu:{tmp_path}/mdp:115200:8N1: no answer to read "
                                       f"of 1 at 9 within 0.3 s (over RTU the MDP is silent for "
                                       f"a unit id without a station: is station 2 configured "
                                       f"at the MDP?)"), out
    assert "+ 220 ms for the RTU line at 115200 baud 8N1 (docs/serial.md)" in out


# name -> (emulator's arguments, the line behind a wrong front and its faults, a PLC writing
# (split?, its line), the probe's stations as (station, line, unit id), the probe's arguments,
# station -> the start of its first line; "ok" is every check passed)
DYN = ["--stations", 2]
STATIC = ["--stations", 2, "--mode", "static", "--static-registers"]
QUICK = ["--watch", "0.3", "--blocks", "3"]
ST = [(1, "trm1", 1), (2, "trm2", 2)]
CASES = {
    "one-based TRM": (DYN, ("trm2", {"one_based": True}), None, ST, QUICK, {
        2: "station 2: FAIL address base: the TRM counts its register addresses from 1",
        1: "ok"}),
    "one-based MDP": (DYN, ("mdp", {"one_based": True}), None, ST[:1], QUICK, {
        1: "station 1: FAIL address base: the MDP counts its register addresses from 1"}),
    "static TRM, dynamic MDP": (DYN, ("trm1", {"static": 123}), None, ST, QUICK, {
        1: "station 1: FAIL transfer mode: static / dynamic mismatch: the MDP is dynamic",
        2: "ok"}),
    "static counts differ": (STATIC + [100], ("trm1", {"static": 123}), None, ST[:1], QUICK, {
        1: "station 1: FAIL transfer mode: static on both, but the counts differ: MDP 100, "
           "TRM 123"}),
    "missing station": (DYN, None, None, ST + [(3, "trm1", 3)], QUICK, {
        3: "station 3: FAIL answers: MDP rtu:{mdp}:115200:8N1: no answer to read of 1 at 9 "
           "within 1 s (over RTU the MDP is silent for a unit id without a station",
        1: "ok", 2: "ok"}),
    "wrong unit id": (DYN, None, None, [(1, "trm2", 2), (2, "trm1", 1)], QUICK, {
        1: "station 1: FAIL unit id: the block written to the MDP under unit id 1 arrived at "
           "the TRM given for station 2",
        2: "station 2: FAIL unit id: the block written to the MDP under unit id 2 arrived at "
           "the TRM given for station 1"}),
    "client splits its blocks": (STATIC + [123], ("trm2", {}), (True, "trm2"), ST,
                                 ["--watch", "1", "--blocks", "3"], {
        2: "station 2: FAIL quiet: a client writes station 2's block at the TRM in parts",
        1: "ok"}),
    "PLC still writing": (DYN[:2], ("trm1", {}), (False, "trm1"), ST[:1],
                          ["--watch", "1", "--blocks", "3"], {
        1: "station 1: FAIL quiet: a PLC writes to station 1: TRM ("}),
    "bit 4 stuck": (DYN[:2], ("trm1", {"sticky_bit4": True}), None, ST[:1], QUICK + ["--timeout", "1"], {
        1: "station 1: FAIL bit 4 up: bit 4 (write data unconfirmed) of the TRM's read status "
           "(2198) never cleared within 1 s"}),
    "silent radio": (DYN[:2] + ["--loss-down", 1, "--loss-up", 1], None, None, ST[:1],
                     QUICK + ["--timeout", "0.5"], {
        1: "station 1: FAIL block down: a block written to the MDP for station 1 never arrived "
           "at the TRM"}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_rtu_wrong_setting_is_named_in_its_first_line(case, tmp_path):
    emu_args, wrong, plc_at, stations, args, want = CASES[case]
    n = emu_args[emu_args.index("--stations") + 1]
    lines = ["--rtu", f"pty:{tmp_path}/emu-mdp:115200=mdp"]
    for s in range(1, n + 1):
        lines += ["--rtu", f"pty:{tmp_path}/emu-trm{s}:115200=trm{s}@{s}"]
    e = Emulator(*FAST, *emu_args, *lines)
    # the probe's port of each line: the emulator's pty itself, or a wrong front's
    port = {"mdp": tmp_path / "emu-mdp", **{f"trm{s}": tmp_path / f"emu-trm{s}"
                                            for s in range(1, n + 1)}}
    front = plc = None
    try:
        if wrong:
            name, faults = wrong
            front = FaultLine(tmp_path / f"emu-{name}", [tmp_path / name, tmp_path / f"{name}-plc"],
                              **faults)
            port[name] = tmp_path / name
        if plc_at:
            split, name = plc_at
            plc = WritingPlc(tmp_path / f"{name}-plc", split=split, cycle=0.03 if split else 0.02,
                             unit=int(name[3:]))
        cmd = [str(PROBE), "--mdp", f"rtu:{port['mdp']}:{LINE}"]
        for s, line, unit in stations:
            cmd += ["--trm", f"{s}=rtu:{port[line]}:{LINE}@{unit}"]
        r = subprocess.run(cmd + [str(a) for a in args], capture_output=True, text=True, timeout=120)
    finally:
        if plc:
            plc.stop()
        if front:
            front.close()
        assert e.stop() == 0
    out = r.stdout
    assert "Traceback" not in out + r.stderr, out + r.stderr
    assert r.returncode == 1, out + r.stderr
    first = {int(m.group(1)): m.group(0) for m in re.finditer(r"^station (\d+): .*$", out, re.M)}
    for s, start in want.items():
        if start == "ok":
            assert first[s] == f"station {s}: ok: every check passed", out
        else:
            assert first[s].startswith(start.format(mdp=port["mdp"])), out
