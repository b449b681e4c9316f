"""The chain over Modbus RTU in real time (issue 27): the demo with --link rtu:BAUD, every PLC on
a pty of the emulator; the trace shows the requests came over RTU (the outstation's unit id 1 on
its TRM line, the central's station unit ids on the MDP line) and the data arrive register for
register (the demo's own check)."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def run_demo(tmp_path, *args, timeout=300):
    return subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--rundir",
                           str(tmp_path / "run"), *args], capture_output=True, text=True,
                          timeout=timeout)


def check(p, tmp_path, records, stations=1):
    assert p.returncode == 0, p.stdout + p.stderr
    last = p.stdout.strip().splitlines()[-1]
    assert last.startswith(f"result: ok records={records * stations} "), last
    assert "PLCs on Modbus RTU at" in p.stdout
    trace = [json.loads(l) for l in (tmp_path / "run" / "emulator-trace.jsonl").read_text().splitlines()]
    modbus = [e for e in trace if e["ev"] == "modbus"]
    assert {e["ep"] for e in modbus} == {"mdp", "trm"}
    assert all(e["exc"] == 0 for e in modbus), [e for e in modbus if e["exc"]][:3]
    # RTU frames reach the core as TCP ADUs with transaction id 0 (TCP clients count from 1)
    assert all(e["tid"] == 0 for e in modbus)


def test_chain_demo_over_rtu_115200(tmp_path):
    check(run_demo(tmp_path, "--link", "rtu:115200", "--records", "3"), tmp_path, 3)


@pytest.mark.slow
def test_chain_demo_over_rtu_19200_realistic_two_stations(tmp_path):
    check(run_demo(tmp_path, "--link", "rtu:19200", "--realistic", "--stations", "2"), tmp_path, 5, 2)


def test_chain_demo_rejects_a_bad_link(tmp_path):
    p = run_demo(tmp_path, "--link", "rtu:12345")
    assert p.returncode == 2
    assert "--link must be tcp or rtu:BAUD" in p.stderr and "Traceback" not in p.stderr
