"""The mip-emulator as a Modbus RTU slave on a pty (issue 27): frames with CRC, silence for bad
CRC, other unit ids and broadcasts, several devices on one bus, the 3.5-character gap ending a
frame, answers not faster than the line, and the same core as over TCP (same trace events)."""
import re
import struct
import subprocess
import time

import pytest

from miptest.emu import BINARY, FAST, Emulator, connect, run_cli, tcp_read
from miptest.rtu import RtuLine, char_s, check_frame, crc16, fc3, fc16, frame


class RtuEmulator(Emulator):
    def __init__(self, *args, trace=None):
        super().__init__(*args, trace=trace)
        # the pty paths follow on the same line (Emulator only parses the TCP part)


def start(tmp_path, *rtu_specs, extra=()):
    args = list(FAST) + list(extra)
    for spec in rtu_specs:
        args += ["--rtu", spec]
    return Emulator(*args, trace=tmp_path / "trace.jsonl")


@pytest.fixture
def two_trms(tmp_path):
    link = tmp_path / "ttyMIP"
    emu = start(tmp_path, f"pty:{link}:19200:8E1=trm1@5,trm2@6", extra=["--stations", "2"])
    line = RtuLine(str(link))
    yield emu, line
    line.close()
    assert emu.stop() == 0


def test_rtu_read_write_and_crc(two_trms):
    emu, line = two_trms
    rsp, _ = line.transact(5, fc16(2001, [42, 43, 44]))
    unit, pdu = check_frame(rsp)
    assert (unit, pdu) == (5, struct.pack(">BHH", 16, 2001, 3))
    rsp, _ = line.transact(5, fc3(2001, 3))
    unit, pdu = check_frame(rsp)
    assert unit == 5
    assert pdu == bytes([3, 6]) + struct.pack(">3H", 42, 43, 44)
    # the same registers over TCP: one core behind both fronts
    assert tcp_read(emu.trm_port(1), 2001, 3) == [42, 43, 44]


def test_rtu_exception_answers_carry_a_crc(two_trms):
    _, line = two_trms
    unit, pdu = check_frame(line.transact(6, bytes([0x2B, 0x0E, 0x01, 0x00]))[0])
    assert (unit, pdu) == (6, bytes([0xAB, 0x01]))
    unit, pdu = check_frame(line.transact(6, fc3(100, 1))[0])
    assert (unit, pdu) == (6, bytes([0x83, 0x02]))


def test_rtu_bad_crc_and_other_unit_ids_get_silence(two_trms):
    emu, line = two_trms
    good = frame(5, fc16(2001, [7]))
    bad = good[:-1] + bytes([good[-1] ^ 0xFF])
    line.send(bad)
    assert line.receive(first_timeout=0.4) == b""
    line.send(frame(9, fc3(2000, 1)))          # nobody on the bus has unit id 9
    assert line.receive(first_timeout=0.4) == b""
    assert tcp_read(emu.trm_port(1), 2001, 1) == [0]   # the bad frame wrote nothing
    # the line still works after the silences
    assert check_frame(line.transact(5, fc3(2000, 1))[0])[0] == 5
    modbus = [e for e in emu.trace() if e["ev"] == "modbus" and e.get("fc") == 16]
    assert modbus == []


def test_rtu_two_devices_on_one_bus_each_answer_their_unit_id(two_trms):
    emu, line = two_trms
    check_frame(line.transact(5, fc16(2001, [501]))[0])
    check_frame(line.transact(6, fc16(2001, [602]))[0])
    assert tcp_read(emu.trm_port(1), 2001, 1) == [501]
    assert tcp_read(emu.trm_port(2), 2001, 1) == [602]


def test_rtu_broadcast_is_taken_by_every_device_and_answered_by_none(two_trms):
    emu, line = two_trms
    line.send(frame(0, fc16(2001, [77, 78])))
    assert line.receive(first_timeout=0.4) == b""
    assert tcp_read(emu.trm_port(1), 2001, 2) == [77, 78]
    assert tcp_read(emu.trm_port(2), 2001, 2) == [77, 78]


def test_rtu_a_pause_longer_than_3_5_characters_ends_the_frame(tmp_path):
    link = tmp_path / "tty"
    emu = start(tmp_path, f"pty:{link}:9600=trm1@1")
    line = RtuLine(str(link))
    try:
        raw = frame(1, fc3(2000, 1))
        line.send(raw[:4])
        time.sleep(0.05)   # 50 ms >> 3.5 characters at 9600 baud (4 ms): two broken frames
        line.send(raw[4:])
        assert line.receive(first_timeout=0.4) == b""
        assert check_frame(line.transact(1, fc3(2000, 1))[0])[0] == 1
    finally:
        line.close()
        assert emu.stop() == 0


@pytest.mark.parametrize("baud", [9600, 19200])
def test_rtu_answers_no_faster_than_the_line_carries_them(tmp_path, baud):
    """An FC16 of 123 registers (255 bytes) and its 8-byte answer, plus two 3.5-character gaps:
    the answer cannot be complete earlier (a lower bound: a slow machine only adds)."""
    link = tmp_path / "tty"
    emu = start(tmp_path, f"pty:{link}:{baud}:8E1=trm1@1")
    line = RtuLine(str(link))
    try:
        rsp, took = line.transact(1, fc16(2001, list(range(123))))
        check_frame(rsp)
        c = char_s(baud, "8E1")
        assert took >= (255 + 8) * c + 2 * 3.5 * c
    finally:
        line.close()
        assert emu.stop() == 0


def test_rtu_mdp_unit_ids_are_the_stations(tmp_path):
    link = tmp_path / "tty"
    emu = start(tmp_path, f"pty:{link}=mdp", extra=["--stations", "2"])
    line = RtuLine(str(link))
    try:
        for st in (1, 2):
            unit, pdu = check_frame(line.transact(st, fc3(9, 1))[0])
            assert unit == st and pdu[:2] == bytes([3, 2])
        line.send(frame(3, fc3(9, 1)))    # no station 3: no answer on a serial line
        assert line.receive(first_timeout=0.4) == b""
    finally:
        line.close()
        assert emu.stop() == 0


def test_rtu_only_without_tcp(tmp_path):
    link = tmp_path / "a:b" / "tty"      # a ':' in the path is no field separator
    link.parent.mkdir()
    p = subprocess.Popen([str(BINARY), "--no-tcp", "--rtu", f"pty:{link}:9600:8N1=trm1@1"],
                         stdout=subprocess.PIPE, text=True)
    try:
        line = p.stdout.readline()
        assert re.match(r"mip-emulator: listening mdp=none trm=none rtu=/dev/pts/\d+$", line.strip()), line
        rl = RtuLine(str(link))
        assert check_frame(rl.transact(1, fc3(2000, 1))[0])[0] == 1
        rl.close()
    finally:
        p.terminate()
        assert p.wait(timeout=10) == 0
        p.stdout.close()
    assert not link.exists(), "the link is removed at exit"


@pytest.mark.parametrize("spec,msg", [
    ("pty", "expected PORT[:BAUD[:FRAME]]=DEVICES"),
    ("pty:123=trm1@1", "baud rate '123' outside 300..4000000"),
    ("pty:19200:9X1=trm1@1", "frame '9X1' is not like 8N1"),
    ("pty=trm2@1", "'trm2@1': no such station"),
    ("pty=trm1@1,trm1@1", "two devices answer the same unit id"),
    ("pty=mdp,trm1@1", "two devices answer the same unit id"),
    ("pty=modem", "device 'modem' is not 'mdp' or 'trmS@UNIT'"),
])
def test_rtu_bad_specs_are_one_line(spec, msg):
    p = run_cli("--rtu", spec)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and msg in p.stderr, p.stderr


def test_rtu_crc_matches_the_modbus_reference():
    # the example of the Modbus serial line guide: 02 07 -> CRC 0x1241, sent 41 12
    assert crc16(bytes([0x02, 0x07])) == 0x1241


def test_rtu_and_tcp_requests_give_the_same_trace_lines(tmp_path):
    """The same requests over TCP (transaction id 0) and over RTU reach the same core: their
    modbus trace lines are equal but for the time and the line number."""
    reqs = [(1, fc16(2001, [11, 12, 13])), (1, fc3(2198, 5)), (1, bytes([0x2B, 0x0E, 0x01, 0x00])),
            (1, fc3(100, 1)), (1, fc3(2198, 126)), (1, fc16(2001, list(range(123))))]
    runs = []
    for kind in ("tcp", "rtu"):
        d = tmp_path / kind
        d.mkdir()
        link = d / "tty"
        emu = Emulator(*FAST, "--rtu", f"pty:{link}=trm1@1", trace=d / "trace.jsonl")
        try:
            if kind == "tcp":
                s = connect(emu.trm_port(1))
                for unit, pdu in reqs:
                    s.sendall(struct.pack(">HHHB", 0, 0, len(pdu) + 1, unit) + pdu)
                    assert s.recv(1024)
                s.close()
            else:
                line = RtuLine(str(link))
                for unit, pdu in reqs:
                    check_frame(line.transact(unit, pdu)[0])
                line.close()
        finally:
            assert emu.stop() == 0
        runs.append([{k: v for k, v in e.items() if k not in ("t", "seq")}
                     for e in emu.trace() if e["ev"] == "modbus"])
    assert len(runs[0]) == len(reqs)
    assert runs[0] == runs[1]


@pytest.mark.parametrize("pause_chars,answered", [(0.5, True), (2.5, False)])
def test_rtu_a_pause_inside_a_frame_over_1_5_characters_breaks_it(tmp_path, pause_chars, answered):
    """t1.5 (Modbus over Serial Line V1.02, section 2.5.1.1) on a real pty: the request's first
    4 characters, then, once they have crossed the line (the emulator times it), a pause, then
    the rest. At 600 baud a character is 16.7 ms, so 0.5 and 2.5 characters are 8 ms from t1.5
    (and 2.5 from t3.5): more than a pty and a loaded machine shift a write. The exact bounds
    (1.4 / 1.6 / 3.4 / 3.6 characters) are tested on the framer with explicit times
    (emulator/tests/test_rtu.c): a pty cannot show 0.2 characters."""
    link = tmp_path / "tty"
    emu = start(tmp_path, f"pty:{link}:600:8N1=trm1@1")
    line = RtuLine(str(link))
    try:
        c = char_s(600, "8N1")
        raw = frame(1, fc3(2000, 1))
        t0 = time.monotonic()
        line.send(raw[:4])
        time.sleep(max(0.0, t0 + (4 + pause_chars) * c - time.monotonic()))
        line.send(raw[4:])
        rsp = line.receive(first_timeout=1.0)
        if answered:
            assert check_frame(rsp)[0] == 1
        else:
            assert rsp == b""
            assert check_frame(line.transact(1, fc3(2000, 1))[0])[0] == 1   # the line still works
    finally:
        line.close()
        assert emu.stop() == 0
