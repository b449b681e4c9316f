"""The test kit's capture (kit/mipkit/capture.py, docs/wireshark.md "Capturing the demo and the
kit"): a failing kit test or mip-kit scenario run with a capture on leaves modbus.pcapng.gz, and
tshark with dist/wireshark/mipmb.lua reads the PLCs' blocks from it; without the option nothing
is kept (the kit's artifacts stay small)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from kit_capture_helpers import central_and_peer
from mipkit import Net
from mipkit.capture import save_for_report
from test_wireshark_dissector import REPO, TSHARK, rows, tshark

pytestmark = pytest.mark.skipif(TSHARK is None and not os.environ.get("CI"),
                                reason="tshark is not installed (Debian package tshark)")
PORTS = []      # the kit's capture needs no preference: the modems are on Modbus's port 502


def writes(pcap):
    return [(r["mipmb.hop"], r["mipmb.record"] or r["mipmb.ack"])
            for r in rows(pcap, *PORTS, display='mipmb.kind == "write request"')]


def test_kit_capture_opens_with_the_dissector(tmp_path):
    """The PLC's and the peer's exchanges with the emulated modems, as Wireshark shows them:
    the note's sequence, each block on its hop, no "Unknown", reads without new data as such."""
    with Net(tmp_path / "net", 1, radio="fast", seed=9, capture_s=30) as net:
        peer = central_and_peer(net, tmp_path)
        assert net.run_until(lambda: peer.done, within_s=120)
        title, text, prop = save_for_report(net, tmp_path / "out")
    pcap = Path(prop[1])
    assert prop[0] == "mip_capture" and pcap.name == "modbus.pcapng.gz" and str(pcap) in text
    assert pcap.stat().st_size < 20_000
    got = writes(pcap)
    want = []
    for n in list(range(1, 7)) + [65535]:
        want += [("outstation PLC -> TRM-810", str(n)), ("central PLC -> MDP-810", str(n))]
    assert ("central PLC -> MDP-810", "0") in got[:2]         # the central's query (note 2.1.1)
    assert [w for w in got if w[1] != "0"][:len(want)] == want
    details = tshark(pcap, *PORTS, "-O", "mipmb", "-Y", "mipmb")
    assert "Unknown" not in details
    assert "Record counter: 65535 (16#FFFF: the last record of the outstation; " \
           "radio outstation->central)" in details
    stale = rows(pcap, *PORTS, display="mipmb.no_new_data")
    assert stale and all("[MIP read, no new data]" in r["_ws.col.Info"] and not r["mipmb.record"]
                         for r in stale)
    # virtual time, from 0: the last write is at the end of the transfer, not in 1970's clock
    t = tshark(pcap, *PORTS, "-Y", 'mipmb.kind == "write request"', "-T", "fields",
               "-e", "frame.time_relative").split()
    assert 0 < float(t[-1]) < 30


def test_kit_capture_is_centred_on_the_fault(tmp_path):
    """capture_s seconds around the failure report's fault (here the central's last delivery),
    not the idle seconds after it; without a fault, the last seconds."""
    with Net(tmp_path / "net", 1, radio="fast", seed=9, capture_s=0.4) as net:
        peer = central_and_peer(net, tmp_path)
        assert net.run_until(lambda: peer.done, within_s=120)
        net.run_for(5)
        end = net.now / 1e9
        _, text, prop = save_for_report(net, tmp_path / "out", "central: 7 records, want 8")
        last = net.capture.save(tmp_path / "last.pcapng", window=net.capture.window())
    assert "around the fault at " in text, text
    pcap = Path(prop[1])
    t = [float(x) for x in tshark(pcap, *PORTS, "-T", "fields", "-e", "frame.time_epoch").split()]
    assert t and max(t) - min(t) <= 0.4 + 1e-6 and max(t) < end - 4, (t[0], t[-1], end)
    assert ("outstation PLC -> TRM-810", "65535") in writes(pcap)
    t = [float(x) for x in tshark(last, *PORTS, "-T", "fields", "-e", "frame.time_epoch").split()]
    assert t and end - 0.4 - 0.05 <= min(t) and max(t) <= end, (t[0], t[-1], end)
    assert not writes(last)                 # the transfer ended 5 s before: only reads


INNER = '''
from kit_capture_helpers import central_and_peer


def test_inner(mip_network, tmp_path):
    net = mip_network(1, radio="fast", seed=9)
    peer = central_and_peer(net, tmp_path)
    assert net.run_until(lambda: peer.done, within_s=120)
    assert not peer.done, "a deliberate failure"
'''


def run_inner(tmp_path, *opts):
    (tmp_path / "test_inner.py").write_text(INNER)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO / "kit"), str(Path(__file__).parent)]))
    env.pop("PYTEST_ADDOPTS", None)
    env.pop("PYTEST_XDIST_WORKER", None)
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "mipkit.plugin",
                           "-p", "no:cacheprovider", "--rootdir", str(tmp_path),
                           "-c", os.devnull, str(tmp_path / "test_inner.py"),
                           "--mip-results", str(tmp_path / "results"), *opts],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)


def test_a_failed_kit_test_leaves_its_capture(tmp_path):
    """pytest --mip-capture 10: the failed test's results folder holds modbus.pcapng.gz, the
    report names it, and it holds the run's blocks; without the option there is none."""
    r = run_inner(tmp_path, "--mip-capture", "10")
    assert r.returncode == 1, r.stdout + r.stderr
    found = list((tmp_path / "results").rglob("modbus.pcapng.gz"))
    assert len(found) == 1, r.stdout
    # the command it prints names the dissector of this checkout
    assert f"{found[0]} (" in r.stdout, r.stdout
    assert f"wireshark -X lua_script:{REPO / 'dist/wireshark/mipmb.lua'} {found[0]}" in r.stdout
    assert ("outstation PLC -> TRM-810", "65535") in writes(found[0])
    assert found[0].stat().st_size < 20_000
    r = run_inner(tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert not list((tmp_path / "results").rglob("*.pcapng*"))
    assert (tmp_path / "results").is_dir()           # the rest of the report is there


@pytest.mark.slow
def test_the_kits_wheel_carries_the_dissector(tmp_path):
    """An integrator's kit (pip install of kit/) has mipmb.lua beside capture.py, and the report's
    command names that copy: no checkout needed to open a capture."""
    import zipfile
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                        "--no-build-isolation", "--no-index", "-w", str(tmp_path),
                        str(REPO / "kit")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (whl,) = tmp_path.glob("mip_logger_kit-*.whl")
    z = zipfile.ZipFile(whl)
    assert z.read("mipkit/mipmb.lua") == (REPO / "dist" / "wireshark" / "mipmb.lua").read_bytes()
    z.extract("mipkit/capture.py", tmp_path / "site")
    z.extract("mipkit/mipmb.lua", tmp_path / "site")
    out = subprocess.run([sys.executable, "-c", "import capture; print(capture.dissector())"],
                         cwd=tmp_path / "site" / "mipkit", capture_output=True, text=True)
    assert out.stdout.strip() == str(tmp_path / "site" / "mipkit" / "mipmb.lua"), out.stderr
