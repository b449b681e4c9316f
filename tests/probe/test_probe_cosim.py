"""Issue 48's validation of the sizing: the parameters mip-probe recommends after probing the
emulator's realistic radio (9600 bit/s, 20 ms gaps, in real time), fed to the example programs
in the co-simulation over the same radio: no needless retransmission at 0 % loss, no failed
transfer at 10 % and 30 %; and at half the recommended tTimeout, retransmissions exactly where the
report's prediction (`retransmits_below_ms`) says: none above it, some below.

Full tier: the probe on the realistic radio takes about 20 s, the co-simulated runs 10-30 s."""
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from miptest.emu import Emulator

pytestmark = pytest.mark.slow
PROBE = Path(sys.executable).parent / "mip-probe"


def cosim(timeout_ms, transfer_timeout_ms, loss, seed=3):
    from mipcosim import programs as L
    from mipcosim.sim import SEC, LoggerLink, Radio, Setup
    st = Setup(radio=Radio.realistic(), records=12, payload=122, timeout_ms=timeout_ms,
               transfer_timeout_s=math.ceil(transfer_timeout_ms / 1000), loss=loss, seed=seed)
    with LoggerLink(st, Path(tempfile.mkdtemp(prefix="probe-cosim-"))) as ch:
        done = ch.run_to_end(1800 * SEC)
        out = {"done": done,
               "retransmissions": ch.mw(("out", 1), L.peer_base(1) + L.S_RETRANS),
               "failed_sender": ch.mw(("out", 1), L.peer_base(1) + L.S_FAILED),
               "failed_central": ch.mw(("cen", 0), L.peer_base(1) + L.R_FAILED),
               "records": ch.mw(("cen", 0), L.peer_base(1) + L.R_TRANSFERS)}
    return out


@pytest.fixture(scope="module")
def recommended(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("probe")
    e = Emulator("--stations", 1)          # the emulator's default: the realistic radio
    try:
        r = subprocess.run([str(PROBE), "--mdp", f"127.0.0.1:{e.mdp_port}",
                            "--trm", f"1=127.0.0.1:{e.trm_port(1)}", "--watch", "0.5",
                            "--report", str(tmp / "r.json")], capture_output=True, text=True,
                           timeout=300)
    finally:
        assert e.stop() == 0
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads((tmp / "r.json").read_text())["recommended"]


@pytest.mark.parametrize("loss", [0.0, 0.1, 0.3])
def test_the_recommended_parameters_carry_the_transfer(recommended, loss):
    p = recommended
    got = cosim(p["tTimeout_ms"], p["tTransferTimeout_ms"], loss)
    assert got["done"] and got["failed_sender"] == 0 and got["failed_central"] == 0, got
    if loss == 0:
        assert got["retransmissions"] == 0, got


def test_half_the_timeout_retransmits_as_the_report_predicts(recommended):
    p = recommended
    half = p["tTimeout_ms"] // 2
    got = cosim(half, p["tTransferTimeout_ms"] // 2, 0.0)
    assert got["done"] and got["failed_sender"] == 0, got
    if half >= p["retransmits_below_ms"]:
        assert got["retransmissions"] == 0, (half, p, got)
    else:
        assert got["retransmissions"] > 0, (half, p, got)
    # and well below the prediction's bound a tTimeout does retransmit (the bound is an upper
    # one: records are full, acknowledgements short)
    low = cosim(p["retransmits_below_ms"] // 4, p["tTransferTimeout_ms"], 0.0)
    assert low["retransmissions"] > 0, (p, low)
