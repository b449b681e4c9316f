"""The SCADA master of the pull way (mippeer/scada.py, `mip-peer scada`) against both relays: the
independent one (mippeer/siprotec.py, in this process) and the emulator's (`mip-emulator --relay`,
in real time): every entry once, in order, time stamps unchanged, the recorder empty after; a lost
acknowledgement answer, a lost acknowledgement and a restarted master take nothing twice; bad
answers and a dead server are one line after bounded retries."""
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mippeer.scada import Client, ScadaError, SoeMaster
from mippeer.siprotec import EventRecorder, RelayConfig, RelayServer

REPO = Path(__file__).resolve().parents[2]
EMULATOR = Path(os.environ.get("MIP_EMULATOR", REPO / "build" / "emulator" / "mip-emulator"))
ORIGIN = 1767225600000
EVENTS = [(k / 1000, [0x0102, 100 + k, 0x0101, k % 2]) for k in range(1, 11)]   # 10 events


def expected(events=EVENTS):
    return [(w[1], ORIGIN + round(t * 1000)) for t, w in events]


def taken(rows):
    return [(r["address"], r["ts_ms"]) for r in rows]


def relay(cls=EventRecorder, **cfg):
    rec = cls(RelayConfig(origin_ms=ORIGIN, **cfg))
    for t, w in EVENTS:
        rec.add(t, w)
    rec.advance(1.0)
    return rec, RelayServer(rec).start()


def drain(master, rows, want, polls=200):
    for i in range(polls):
        if len(rows) >= want:
            return
        try:
            master.poll(float(i))
        except ScadaError:
            pass
    raise AssertionError(f"{len(rows)} of {want} entries after {polls} polls")


def test_takes_every_entry_of_the_independent_relay_once_in_order():
    rec, srv = relay()
    rows = []
    m = SoeMaster(Client("127.0.0.1", srv.port), sink=rows.extend)
    drain(m, rows, 10)
    assert taken(rows) == expected()
    assert [r["type_bit"] for r in rows] == [0x0102] * 10 and [r["value"] for r in rows] == [k % 2 for k in range(1, 11)]
    assert [r["seq"] for r in rows] == [1, 1, 1, 2, 2, 2, 3, 3, 3, 4]
    assert rec.registers()[:2] == [0, 4]          # empty; the last sequence number, no blocks
    assert (m.acks, m.refused) == (4, 0)
    srv.shutdown()


def test_a_lost_acknowledgement_answer_takes_nothing_twice():
    rec, srv = relay()
    rows = []
    m = SoeMaster(Client("127.0.0.1", srv.port), sink=rows.extend)
    m.lose_answers = {1, 2}
    drain(m, rows, 10)
    assert taken(rows) == expected()
    assert rec.registers()[0] == 0
    srv.shutdown()


class LosesFirstAck(EventRecorder):
    """The first acknowledgement never arrives (lost on the way there)."""
    lost = False

    def _control(self, v):
        if not self.lost:
            self.lost = True
            return
        super()._control(v)


def test_a_lost_acknowledgement_is_repeated_and_the_entries_not_taken_again():
    rec, srv = relay(LosesFirstAck)
    rows = []
    m = SoeMaster(Client("127.0.0.1", srv.port), sink=rows.extend, reack=0.0)
    drain(m, rows, 10)
    assert taken(rows) == expected()
    assert m.reacks == 1 and rec.registers()[0] == 0
    srv.shutdown()


def cli(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "mippeer.cli", "scada", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


class Ran:
    def __init__(self, returncode, out, err):
        self.returncode, self.stdout, self.stderr = returncode, out, err


@pytest.fixture
def inproc(monkeypatch, capsys):
    """`mip-peer scada` run in this process (a subprocess costs a second of start-up here)."""
    from mippeer import cli as mcli
    monkeypatch.setattr(signal, "signal", lambda *a: None)

    def run(*args):
        try:
            rc = mcli.main(["scada", *map(str, args)])
        except SystemExit as e:
            rc = e.code
        out = capsys.readouterr()
        return Ran(rc, out.out, out.err)
    return run


def test_a_restarted_master_does_not_take_the_last_offer_of_its_file_again(tmp_path, inproc):
    rec, srv = relay(LosesFirstAck)
    out = tmp_path / "e.jsonl"
    # the first run takes the first offer; its acknowledgement is lost; it stops
    p = inproc("--port", srv.port, "--out", out, "--entries", 3, "--interval", 0)
    assert p.returncode == 0, p.stderr
    assert rec.registers()[:2] == [10, 1 | 3 << 8]          # still offered
    p = inproc("--port", srv.port, "--out", out, "--entries", 7, "--interval", 0.01, "--reack", 0)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "mip-peer scada: entries=7 acks=4 reacks=1 refused=0"
    rows = [json.loads(x) for x in out.read_text().splitlines()]
    assert taken(rows) == expected()
    assert [r["offer"] for r in rows] == [1, 1, 1, 2, 2, 2, 3, 3, 3, 4]
    srv.shutdown()


@pytest.fixture
def emulator_relay(tmp_path):
    if not EMULATOR.is_file():
        pytest.skip(f"{EMULATOR} not built: run `make`")
    script = tmp_path / "events.txt"
    script.write_text("".join(f"{t:.3f} {w[0]:#06x} {w[1]} {w[2]:#06x} {w[3]}\n" for t, w in EVENTS))
    proc = subprocess.Popen([str(EMULATOR), "--mdp-port", "0", "--trm-base-port", "0", "--relay",
                             f"0:origin={ORIGIN},script={script}"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    m = re.search(r" relay=(\d+)$", proc.stdout.readline().strip())
    assert m, proc.stderr.read()
    yield int(m.group(1))
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=10)
    proc.stdout.close()
    proc.stderr.close()


def test_takes_every_entry_of_the_emulators_relay_once_in_order(emulator_relay, tmp_path):
    out = tmp_path / "e.jsonl"
    before = time.monotonic_ns()
    p = cli("--port", emulator_relay, "--out", out, "--entries", 10, "--interval", 0.02)
    after = time.monotonic_ns()
    assert p.returncode == 0, p.stderr
    rows = [json.loads(x) for x in out.read_text().splitlines()]
    assert taken(rows) == expected()
    # when each was taken, on CLOCK_MONOTONIC (mip-emulator's trace clock): the view draws it
    took = [r["mono_ns"] for r in rows]
    assert before <= took[0] and took == sorted(took) and took[-1] <= after
    c = Client("127.0.0.1", emulator_relay)
    assert c.read_holding(600, 2)[0] == 0                   # the recorder is empty
    c.close()


def test_a_dead_server_is_one_line_after_the_retries(tmp_path, inproc):
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]                           # nobody listens there
    p = inproc("--port", port, "--out", tmp_path / "e.jsonl", "--retries", 3, "--interval", 0)
    assert p.returncode == 1
    assert p.stderr.strip() == (f"mip-peer scada: error: 127.0.0.1:{port}: Connection refused "
                                "(3 polls in a row failed)")


class Garbage(EventRecorder):
    """SOE_Control claims 5 blocks (at most 3 exist)."""

    def registers(self):
        regs = super().registers()
        regs[1] = 1 | 5 << 8
        return regs


def test_a_bad_soe_control_is_never_taken(tmp_path, inproc):
    rec, srv = relay(Garbage)
    out = tmp_path / "e.jsonl"
    p = inproc("--port", srv.port, "--out", out, "--retries", 2, "--interval", 0)
    assert p.returncode == 1
    assert p.stderr.strip() == ("mip-peer scada: error: bad SOE_Control 1281 (sequence 1, 5 blocks) "
                                "with count 10: at most 3 blocks, a sequence number, at least as many "
                                "entries as blocks (2 polls in a row failed)")
    assert out.read_text() == ""
    assert rec.registers()[0] == 10
    srv.shutdown()


def test_bad_options_are_one_line(tmp_path, inproc):
    p = inproc("--port", 1, "--out", tmp_path / "e", "--base", 70000)
    assert p.returncode == 2 and p.stderr.strip() == "mip-peer scada: error: --base must be 0..65510"
    (tmp_path / "bad.jsonl").write_text("{\n")
    p = inproc("--port", 1, "--out", tmp_path / "bad.jsonl")
    assert p.returncode == 2
    assert p.stderr.strip() == f"mip-peer scada: error: {tmp_path / 'bad.jsonl'}:1: not a JSON line"
    p = inproc("--port", 1, "--out", tmp_path)
    assert p.returncode == 2 and p.stderr.strip() == f"mip-peer scada: error: {tmp_path}: Is a directory"
