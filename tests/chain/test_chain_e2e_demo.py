"""The chain's real-time demo (`make run RUN_ARGS=--chain`, plc/demo.py --chain, mipdemo.chain):
mip-emulator with a relay -> outstation soft-PLC -> emulated radio -> central soft-PLC ->
`mip-peer scada`; and the committed runtime configs of the chain's programs."""
import re
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


def test_make_run_chain_lossless_full_records_are_not_sent_twice(tmp_path):
    """At 0 % loss no record is written again: 45 events at once fill records of 15 entries,
    which wait for 5 polls of the SCADA (3 entries each, every 0.1 s) before the central
    acknowledges them; the blocks' timeout covers that (with the radio's 300 ms alone this run
    gave retransmissions=3). The demo says how it sized the timeout and which ports it took."""
    p = subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--chain", "--events", "45",
                        "--every-ms", "5", "--rundir", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=120)
    out = p.stdout
    last = out.strip().splitlines()[-1]
    assert p.returncode == 0 and last.startswith("result: ok events=45 "), out[-2000:] + p.stderr
    assert " retransmissions=0 duplicates=0 " in last, last
    assert ("demo: the MIP blocks' timeout 900 ms: the radio's 300 ms + 600 ms for the hand-over "
            "(6 SCADA polls every 0.1 s: a record of 15 entries, 3 a poll,") in out, out
    emu = re.search(r"^demo: mip-emulator: listening mdp=127\.0\.0\.1:(\d+) trm=(\d+) relay=(\d+)$",
                    out, re.M)
    ports = re.search(r"^demo: ports \(free ones\): relay 127\.0\.0\.1:(\d+), TRM-810 "
                      r"127\.0\.0\.1:(\d+), MDP-810 127\.0\.0\.1:(\d+), the central soft-PLC's "
                      r"Modbus slave 127\.0\.0\.1:(\d+) \(the SCADA polls it, the demo reads the "
                      r"status words\), the outstation's 127\.0\.0\.1:(\d+) \(status words\)$", out, re.M)
    assert emu and ports, out
    relay, trm, mdp, cen, outst = ports.groups()
    assert (mdp, trm, relay) == emu.groups()            # the ports the emulator took
    assert len({relay, trm, mdp, cen, outst}) == 5


def test_the_handover_timeout_is_serial_mds_rule_over_the_scadas_polls():
    """What the hand-over adds to the demo's timeout (mipprobe.sizing, the rule of
    docs/serial.md): a poll per 3 entries and the one the record just missed, every interval."""
    from mipprobe.sizing import added_ms, handover_polls, handover_timeout_ms
    from mippeer.scada import BLOCKS
    assert BLOCKS == 3
    assert [handover_polls(n, BLOCKS) for n in (1, 3, 4, 15)] == [2, 2, 3, 6]
    assert handover_timeout_ms(15, BLOCKS, 0.1) == 600 == added_ms(6, 0.1)
    assert handover_timeout_ms(3, BLOCKS, 0.05) == 100
    assert handover_timeout_ms(15, BLOCKS, 10) + 3000 <= 65535     # a WORD at the largest options


def test_make_run_help_lists_the_chain():
    """`make run RUN_ARGS=--help` (plc/demo.py --help) names --chain and where its options are."""
    p = subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--help"],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    text = " ".join(p.stdout.split())
    assert "--chain the whole chain instead" in text and "`--chain --help` lists its options" in text


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
    assert "demo: the MIP blocks' timeout 300 ms: the radio's; the push way's hand-over adds no wait" \
        in p.stdout, p.stdout
    assert re.search(r"^demo: ports \(free ones\): .*UNICOS drivers A 127\.0\.0\.1:\d+ and B "
                     r"127\.0\.0\.1:\d+, ", p.stdout, re.M), p.stdout
