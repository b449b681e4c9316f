"""Interoperability with the note-only Python peer (peers/mippeer, pymodbus, strict reading):
the st_lib outstation soft-PLC against the Python central, and the Python outstation against
the st_lib central, both over the real mip-emulator in real time on 127.0.0.1, polled and
spontaneous, with a one-record transfer (the note peer sends it as a lone 16#FFFF)."""
import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mipcosim import programs as L
from mipdemo import common as demo   # the demos' process and slave helpers
from mipdemo.logger import build_programs
from mippeer.cli import logger_records

REPO = Path(__file__).resolve().parents[2]

EMU = REPO / "build" / "emulator" / "mip-emulator"
PEER = [sys.executable, "-m", "mippeer.cli"]
if not EMU.is_file():
    pytest.fail("build/emulator/mip-emulator not built: run make first (these tests cannot run without it)", pytrace=False)


@pytest.fixture(scope="module")
def progs(tmp_path_factory):
    return build_programs(tmp_path_factory.mktemp("interop-build"))


class Net:
    def __init__(self, tmp, loss=0.1, seed=3):
        self.tmp = tmp
        self.procs = demo.Procs()
        p = self.procs.start("mip-emulator",
                             [str(EMU), "--mdp-port", "0", "--trm-base-port", "0", "--stations",
                              "1", "--loss-up", str(loss), "--loss-down", str(loss), "--seed",
                              str(seed), "--bitrate", "1000000", "--slot-gap-ms", "1"],
                             tmp / "emu.log", stdout=subprocess.PIPE, text=True)
        line = p.stdout.readline()
        fields = dict(kv.split("=", 1) for kv in line.split()[2:])
        self.mdp = int(fields["mdp"].rsplit(":", 1)[1])
        self.trm = int(fields["trm"])
        self.slaves = []
        for port in (self.mdp, self.trm):
            self._wait_accepting(port)

    def _wait_accepting(self, port):
        # the peer connects once, with no retry: make sure the emulator is there first
        deadline = time.monotonic() + 10
        while True:
            self.procs.check_alive()
            try:
                socket.create_connection(("127.0.0.1", port), timeout=2).close()
                return
            except OSError as e:
                if time.monotonic() > deadline:
                    raise AssertionError(f"mip-emulator does not accept on {port}: {e}")
                time.sleep(0.1)

    def plc(self, exe, conf_text, name):
        conf = self.tmp / f"{name}.conf"
        conf.write_text(conf_text)
        port = demo.free_port()
        self.procs.start(name, [str(exe), "-c", str(conf), "-s", f"127.0.0.1:{port}"],
                         self.tmp / f"{name}.log")
        sl = demo.Slave(port)
        sl.connect(time.monotonic() + 10)
        self.slaves.append(sl)
        return sl

    def close(self):
        for sl in self.slaves:
            sl.close()
        self.procs.stop()


@pytest.fixture(scope="module")
def progs_bidi(tmp_path_factory):
    from plcharness.build import build_program
    out = tmp_path_factory.mktemp("interop-build-bidi")
    return {role: build_program(L.program_sources(role, True), out / role)
            for role in ("outstation", "central")}


@pytest.fixture
def net(tmp_path):
    n = Net(tmp_path)
    yield n
    n.close()


@pytest.mark.parametrize("records", [5, 1])
@pytest.mark.parametrize("drive", ["spontaneous", "polled"])
def test_chain_interop_stlib_outstation_to_python_central(net, progs, tmp_path, drive, records):
    out = net.plc(progs["outstation"].executable, L.outstation_config(net.trm), "outstation")
    params = L.Params(records=records, payload=20, session=9, station=1,
                      polled=drive == "polled", timeout_ms=500)
    out.write(0, params.words())
    received = tmp_path / "received.json"
    peer = subprocess.run(PEER + ["central", "--port", str(net.mdp), "--unit", "1",
                                  "--drive", drive, "--expect", "1", "--period", "0.02",
                                  "--retransmit", "0.5", "--request", "0.5",
                                  "--timeout", "60", "--out", str(received)],
                          capture_output=True, text=True, timeout=90)
    assert peer.returncode == 0, peer.stderr + peer.stdout
    got = json.loads(received.read_text())
    want = [L.log_record(n, 20, 9, 1) for n in range(1, records + 1)]
    # the Python central keeps the records of a transfer as payload lists; an empty last
    # record (st_lib's one-record transfer: record 1, then an empty 16#FFFF) holds nothing
    assert [r for r in got["transfers"][0] if r] == want
    assert got["abandoned"] == [] and got["open"] == []
    # and the st_lib sender saw its transfer acknowledged
    deadline = time.monotonic() + 10
    while out.read(L.peer_base(1) + L.S_ALL, 1)[0] != 1 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert out.read(L.peer_base(1) + L.S_ALL, 1)[0] == 1
    assert out.read(L.peer_base(1) + L.S_FAILED, 1)[0] == 0


@pytest.mark.parametrize("records", [5, 1])
@pytest.mark.parametrize("drive", ["spontaneous", "polled"])
def test_chain_interop_python_outstation_to_stlib_central(net, progs, drive, records):
    cen = net.plc(progs["central"].executable, L.central_config(net.mdp, 1), "central")
    cen.write(0, L.Params(polled=drive == "polled", timeout_ms=500).words())
    size = 20
    peer = subprocess.run(PEER + ["outstation", "--port", str(net.trm), "--unit", "1",
                                  "--drive", drive, "--records", str(records), "--record-size",
                                  str(size), "--seed", "4", "--period", "0.02",
                                  "--retransmit", "0.5", "--request", "0.5", "--timeout", "20"],
                          capture_output=True, text=True, timeout=60)
    assert peer.returncode == 0, peer.stderr + peer.stdout
    stream = [w for rec in logger_records(records, size, 4) for w in rec]
    deadline = time.monotonic() + 10
    b = L.peer_base(1)
    while time.monotonic() < deadline:
        blk = cen.read(b, 40)
        if blk[L.R_COM_LO] + (blk[L.R_COM_HI] << 16) >= len(stream):
            break
        time.sleep(0.05)
    blk = cen.read(b, 40)
    win = cen.read(b + L.W_BASE, L.WINDOW)
    assert blk[L.R_COM_LO] + (blk[L.R_COM_HI] << 16) == len(stream)
    assert (blk[L.R_SUM_A], blk[L.R_SUM_B]) == L.fletcher(stream)
    assert [win[p % L.WINDOW] for p in L.committed_positions(blk)] == \
        [stream[p] for p in L.committed_positions(blk)]
    assert blk[L.R_TRANSFERS] == 1 and blk[L.R_FAILED] == 0


# Restarts of either side, static mode and the strict/lenient readings of the note are cells of
# the interop matrix (tests/interop/, python -m mipinterop); this file keeps the drives (polled,
# spontaneous) and the one-record transfer, which the matrix does not vary.

def _wait(cond, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.05)
    return cond()


# ---------------------------------------------------------------- bidirectional (note 2.2)

def _store_matches(sl, stream, base=L.peer_base(1)):
    def committed():
        blk = sl.read(base, 40)
        return blk[L.R_COM_LO] + (blk[L.R_COM_HI] << 16)
    _wait(lambda: committed() >= len(stream), 15)
    blk = sl.read(base, 40)
    win = sl.read(base + L.W_BASE, L.WINDOW)
    assert committed() == len(stream)
    assert (blk[L.R_SUM_A], blk[L.R_SUM_B]) == L.fletcher(stream)
    assert [win[p % L.WINDOW] for p in L.committed_positions(blk)] == \
        [stream[p] for p in L.committed_positions(blk)]


@pytest.mark.parametrize("drive", ["spontaneous", "polled"])
def test_chain_interop_bidirectional_stlib_outstation_python_central(net, progs_bidi, tmp_path,
                                                                    drive):
    out = net.plc(progs_bidi["outstation"].executable, L.outstation_config(net.trm), "outstation")
    out.write(0, L.Params(records=5, payload=20, session=3, polled=drive == "polled",
                          timeout_ms=500).words())
    received = tmp_path / "received.json"
    peer = subprocess.run(PEER + ["central", "--port", str(net.mdp), "--unit", "1", "--layout",
                                  "bi", "--drive", drive, "--records", "6", "--record-size",
                                  "20", "--seed", "6", "--expect", "1", "--period", "0.02",
                                  "--retransmit", "0.5", "--request", "0.5", "--timeout", "60",
                                  "--out", str(received)],
                          capture_output=True, text=True, timeout=90)
    assert peer.returncode == 0, peer.stderr + peer.stdout
    got = json.loads(received.read_text())
    assert [r for r in got["transfers"][0] if r] == [L.log_record(n, 20, 3, 1)
                                                     for n in range(1, 6)]
    _store_matches(out, [w for rec in logger_records(6, 20, 6) for w in rec])


@pytest.mark.parametrize("drive", ["spontaneous", "polled"])
def test_chain_interop_bidirectional_python_outstation_stlib_central(net, progs_bidi, tmp_path,
                                                                    drive):
    cen = net.plc(progs_bidi["central"].executable, L.central_config(net.mdp, 1), "central")
    cen.write(0, L.Params(records=4, payload=20, session=5, polled=drive == "polled",
                          timeout_ms=500).words())
    received = tmp_path / "received.json"
    peer = subprocess.run(PEER + ["outstation", "--port", str(net.trm), "--unit", "1",
                                  "--layout", "bi", "--drive", drive, "--records", "7",
                                  "--record-size", "20", "--seed", "8", "--expect", "1",
                                  "--period", "0.02", "--retransmit", "0.5", "--request", "0.5",
                                  "--timeout", "60", "--out", str(received)],
                          capture_output=True, text=True, timeout=90)
    assert peer.returncode == 0, peer.stderr + peer.stdout
    got = json.loads(received.read_text())
    assert [r for r in got["transfers"][0] if r] == [L.log_record(n, 20, 5 ^ 0x8000, 1)
                                                     for n in range(1, 5)]
    _store_matches(cen, [w for rec in logger_records(7, 20, 8) for w in rec])
