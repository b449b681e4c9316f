"""The chain's real-time demo (`make run RUN_ARGS=--chain`, plc/demo_chain.py): mip-emulator with a
relay -> outstation soft-PLC -> emulated radio -> central soft-PLC -> `mip-peer scada`; and the
committed runtime configs of the chain's programs."""
import subprocess
import sys
from pathlib import Path

import pytest

from mipcosim import chain as C
from plcharness.build import build_program

REPO = Path(__file__).resolve().parents[2]


def test_make_run_chain_delivers_every_event_once(tmp_path):
    p = subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--chain", "--events", "30",
                        "--every-ms", "40", "--loss", "0.1", "--rundir", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=120)
    last = p.stdout.strip().splitlines()[-1]
    assert p.returncode == 0 and last.startswith("result: ok events=30 "), p.stdout[-2000:] + p.stderr
    assert "relay -> SCADA [" in p.stdout            # the progress display


def test_demo_chain_bad_option_is_one_line():
    p = subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--chain", "--per-record", "0"],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "--per-record must be 1..15" in p.stderr
    assert "Traceback" not in p.stderr


def test_committed_chain_configs_are_generated_and_load(tmp_path):
    assert (REPO / "plc" / "outstation_soe.conf").read_text() == C.outstation_soe_config()
    assert (REPO / "plc" / "central_soe.conf").read_text() == C.central_soe_config(slave_port=1502)
    for role, conf in (("out", "outstation_soe.conf"), ("cen", "central_soe.conf")):
        res = build_program(C.program_sources(role), tmp_path / role)
        p = subprocess.run([str(res.executable), "-c", str(REPO / "plc" / conf), "--check"],
                           capture_output=True, text=True)
        assert p.returncode == 0, p.stderr


@pytest.mark.slow
def test_make_run_chain_on_the_realistic_radio_at_30_percent_loss(tmp_path):
    p = subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--chain", "--events", "60",
                        "--realistic", "--loss", "0.3", "--rundir", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=300)
    last = p.stdout.strip().splitlines()[-1]
    assert p.returncode == 0 and last.startswith("result: ok events=60 "), p.stdout[-2000:] + p.stderr


@pytest.mark.slow
def test_make_run_chain_push_to_the_unicos_pair(tmp_path):
    """--handover push: the central writes UNICOS frames to `mip-peer unicos` (a redundant pair);
    driver A's file holds every event once, in order, with its 10 ms time stamp."""
    p = subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--chain", "--handover", "push",
                        "--events", "40", "--loss", "0.1", "--rundir", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=300)
    last = p.stdout.strip().splitlines()[-1]
    assert p.returncode == 0 and last.startswith("result: ok events=40 "), p.stdout[-2000:] + p.stderr
    assert "relay -> WinCC OA [" in p.stdout
