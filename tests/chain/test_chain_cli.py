"""mip-cosim (`make soak` runs `python -m mipcosim.cli soak`): a small soak with restarts
through the same code path, and its one-line errors."""
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def cli(*args, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO / "cosim"))
    return subprocess.run([sys.executable, "-m", "mipcosim.cli", *args, "--workdir",
                           str(tmp_path)], capture_output=True, text=True, env=env, timeout=600)


def test_chain_cli_small_soak_with_restarts(tmp_path):
    p = cli("soak", "--records", "3000", "--per-transfer", "200", "--restart-every", "15",
            "--seed", "3", tmp_path=tmp_path)
    last = p.stdout.strip().splitlines()[-1]
    assert p.returncode == 0, p.stdout + p.stderr
    fields = dict(kv.split("=") for kv in last.split()[2:])
    assert last.startswith("result: ok records=3000 ")
    assert fields["lost"] == "0" and fields["duplicated"] == "0"
    assert int(fields["restarts"]) >= 2 and int(fields["failed_and_reported"]) >= 1
    assert "PEER_RESET" in p.stdout or "SENDER_RESET" in p.stdout


def test_chain_cli_bad_option_one_line(tmp_path):
    p = cli("soak", "--records", "70000", "--per-transfer", "0", tmp_path=tmp_path)
    assert p.returncode == 2
    assert "more than 65534 records need --per-transfer" in p.stderr
    assert "Traceback" not in p.stderr


def test_chain_cli_stations_and_tick_out_of_range_one_line(tmp_path):
    for args, msg in [(["--stations", "6"], "--stations must be in 1..4"),
                      (["--tick-ms", "0"], "--tick-ms must be in 1..1000"),
                      (["--transport", "udp"], "invalid choice: 'udp'")]:
        p = cli("run", *args, tmp_path=tmp_path)
        assert p.returncode == 2, (args, p.stderr)
        assert msg in p.stderr and "Traceback" not in p.stderr


def test_chain_cli_tcp_transport_same_result_as_the_kernel(tmp_path):
    """The same run over Modbus TCP on 127.0.0.1 and through the in-process transport."""
    out = {}
    for tr in ("tcp", "inproc"):
        p = cli("run", "--records", "8", "--loss", "0.2", "--seed", "4", "--transport", tr,
                tmp_path=tmp_path / tr)
        assert p.returncode == 0, p.stdout + p.stderr
        lines = [l for l in p.stdout.splitlines() if l.startswith(("result:", "  radio:"))]
        out[tr] = [l.split(" in ")[0] if l.startswith("  radio:") else
                   " ".join(w for w in l.split() if not w.startswith("seconds=")) for l in lines]
    assert out["tcp"] == out["inproc"] and out["tcp"][-1].startswith("result: ok records=8")


def test_chain_cli_warm_bidi_soak_says_the_window_the_senders_ran(tmp_path):
    """--warm-restarts with --bidi (MIP_Link's gate) and --window 2: accepted, run with
    uWindow 2 as the programs would be configured; a retained sender runs window 1, and so
    does MIP_Link (P27), and the result line says so; the unidirectional soak without --warm
    runs window 2."""
    args = ("soak", "--bidi", "--window", "2", "--records", "400", "--per-transfer", "50",
            "--restart-every", "7")
    warm = cli(*args, "--warm-restarts", tmp_path=tmp_path / "warm")
    assert warm.returncode == 0, warm.stdout + warm.stderr
    last = warm.stdout.strip().splitlines()[-1]
    assert last.startswith("result: ok warm: records=800 lost 0 duplicated 0 failed 0 "), last
    assert " window 1 (uWindow 2) " in last
    cold = cli(*args, tmp_path=tmp_path / "cold")
    assert cold.returncode == 0, cold.stdout + cold.stderr
    assert " window 1 (uWindow 2) seconds=" in cold.stdout.strip().splitlines()[-1]
    uni = cli(*[a for a in args if a != "--bidi"], tmp_path=tmp_path / "uni")
    assert uni.returncode == 0, uni.stdout + uni.stderr
    assert " window 2 seconds=" in uni.stdout.strip().splitlines()[-1]
