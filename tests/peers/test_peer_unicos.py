"""The WinCC OA UNICOS-driver stand-in (peers/mippeer/unicos.py): it tells UNICOS frames from
Modbus frames by the reference number, decodes status tables and 16/32-bit events, refuses what
breaks the rules with exception 03, writes JSON lines, runs as a pair, goes down and comes back;
its command's errors are one line. A pymodbus client (not our code) is the PLC."""
import json
import re
import signal
import socket
import struct
import subprocess
import sys
import time

import pytest
from pymodbus.client import ModbusTcpClient

from mippeer.unicos import DriverPair, DriverServer, UnicosConfig, UnicosDriver, ticks_to_utc

T = 176722560000            # 2026-01-01 00:00:00 UTC in 10 ms


def adu(pdu, tid=1, unit=4):
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def fc16(addr, regs):
    return struct.pack(f">BHHB{len(regs)}H", 16, addr, len(regs), 2 * len(regs), *regs)


def t3(ticks):
    return [(ticks >> 32) & 0xFFFF, (ticks >> 16) & 0xFFFF, ticks & 0xFFFF]


def test_event_frames_are_decoded_with_utc_time_stamps(tmp_path):
    out = tmp_path / "ev.jsonl"
    d = UnicosDriver("A", out=str(out))
    regs32 = [0x1102, 100] + [0x0102, 1] + t3(T + 1) + [101] + [0x0103, 0] + t3(T + 2)
    r = d.handle(adu(fc16(0xFFFF, regs32)))
    assert r[7:] == bytes([16, 0xFF, 0xFF, 0, len(regs32)])          # the normal FC16 answer
    regs16 = [0x1201, 7, 0xBEEF] + t3(T + 8640000)
    assert not d.handle(adu(fc16(0xFFFF, regs16)))[7] & 0x80
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert [(e["sub"], e["offset"], e["value"], e["ts_10ms"], e["plc"]) for e in lines] == [
        (0x11, 100, 0x01020001, T + 1, 4), (0x11, 101, 0x01030000, T + 2, 4),
        (0x12, 7, 0xBEEF, T + 8640000, 4)]
    assert lines[0]["utc"] == "2026-01-01T00:00:00.010Z"
    assert lines[2]["utc"] == "2026-01-02T00:00:00.000Z"
    # when each frame came (CLOCK_MONOTONIC, the emulator trace's clock): one time a frame
    assert lines[0]["mono_ns"] == lines[1]["mono_ns"] <= lines[2]["mono_ns"] <= time.monotonic_ns()
    assert d.frames == 2 and len(d.events) == 3


def test_little_endian_register_order():
    d = UnicosDriver(cfg=UnicosConfig(little_endian_register=True))
    ticks = list(reversed(t3(T + 5)))
    d.handle(adu(fc16(0xFFFF, [0x1101, 9, 0x0001, 0x0102] + ticks)))
    assert d.events[0]["value"] == 0x01020001 and d.events[0]["ts_10ms"] == T + 5


def test_status_table_is_kept_per_offset():
    d = UnicosDriver()
    table = list(range(96))
    assert not d.handle(adu(fc16(0xFFFF, [0x0100, 200] + table)))[7] & 0x80
    assert d.status[(4, 200)] == table and d.events == []
    # 97 words is more than a table
    r = d.handle(adu(fc16(0xFFFF, [0x0100, 200] + table + [1])))
    assert r[7:] == bytes([0x90, 3])


def test_the_reference_number_decides_unicos_or_modbus():
    d = UnicosDriver(cfg=UnicosConfig(marker=0x8000))
    regs = [0x1201, 7, 1] + t3(T)
    d.handle(adu(fc16(0xFFFF, regs)))                   # plain Modbus at 0xFFFF..: out of range
    assert d.events == [] and d.refused == 1
    d.handle(adu(fc16(100, regs)))                      # plain holding registers
    assert d.events == [] and d.holding[100] == 0x1201
    d.handle(adu(fc16(0x8000, regs)))                   # the configured marker
    assert len(d.events) == 1


@pytest.mark.parametrize("regs,why", [
    ([0x1302, 1, 2, 0, 0, 0], "unknown subfunction 16#13"),
    ([0x1102, 100, 0, 1] + t3(T), "header says 2 events, 1 given"),
    ([0x1100], "no events"),
    ([0x1201, 7, 1] + t3(T) + [0], "a register too many"),
])
def test_broken_frames_are_refused_with_exception_03(regs, why):
    d = UnicosDriver()
    r = d.handle(adu(fc16(0xFFFF, regs)))
    assert r[7:] == bytes([0x90, 3]), why
    assert d.events == [] and d.frames == 0


def test_a_frame_over_253_bytes_is_refused():
    d = UnicosDriver()
    fits = [0x1218] + sum(([i, i] + t3(T + i) for i in range(24)), [])    # 24 events: 121 registers
    pdu = fc16(0xFFFF, fits)
    assert len(pdu) == 248 and not d.handle(adu(pdu))[7] & 0x80
    big = struct.pack(">BHHB", 16, 0xFFFF, 124, 248) + struct.pack(">124H", *([0x1218] + [0] * 123))
    assert len(big) == 254
    assert d.handle(adu(big))[7:] == bytes([0x90, 3])
    assert len(d.events) == 24 and d.refused == 1


def test_faults_for_tests_mute_and_exceptions():
    d = UnicosDriver()
    frame = adu(fc16(0xFFFF, [0x1201, 7, 1] + t3(T)))
    d.fail_next(2, code=6)
    assert d.handle(frame)[7:] == bytes([0x90, 6])
    assert d.handle(frame)[7:] == bytes([0x90, 6])
    d.mute = True
    assert d.handle(frame) is None
    d.mute = False
    assert not d.handle(frame)[7] & 0x80 and len(d.events) == 1


def test_a_repeated_event_is_marked_a_duplicate():
    d = UnicosDriver()
    one = adu(fc16(0xFFFF, [0x1201, 7, 1] + t3(T)))
    d.handle(one)
    d.handle(adu(fc16(0xFFFF, [0x1201, 7, 0] + t3(T))))         # another value: not a repeat
    d.handle(one)
    assert [e["duplicate"] for e in d.events] == [False, False, True] and d.duplicates == 1


def _write(port, regs):
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
    assert c.connect()
    try:
        return c.write_registers(0xFFFF, regs, device_id=1)
    finally:
        c.close()


def test_a_pair_over_tcp_taken_down_and_brought_back(tmp_path):
    out = tmp_path / "pair.jsonl"
    pair = DriverPair(out=str(out))
    try:
        ev = [0x1201, 7, 1] + t3(T)
        assert not _write(pair.a.port, ev).isError()
        assert not _write(pair.b.port, ev).isError()
        port = pair.a.port
        pair.a.down()
        with pytest.raises(OSError):
            socket.create_connection(("127.0.0.1", port), timeout=2).close()
        pair.a.up()
        assert pair.a.port == port
        assert not _write(port, [0x1201, 8, 0] + t3(T + 1)).isError()
        drivers = [json.loads(x)["driver"] for x in out.read_text().splitlines()]
        assert sorted(drivers) == ["A", "A", "B"]
        assert [e["offset"] for e in pair.a.driver.events] == [7, 8]
    finally:
        pair.close()


def test_down_cuts_an_open_connection():
    srv = DriverServer(UnicosDriver())
    try:
        c = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=2, retries=0)
        assert c.connect()
        assert not c.write_registers(0xFFFF, [0x1201, 7, 1] + t3(T), device_id=1).isError()
        srv.down()
        time.sleep(0.1)
        r = None
        try:
            r = c.write_registers(0xFFFF, [0x1201, 7, 1] + t3(T), device_id=1)
        except Exception:       # pymodbus raises ConnectionException on a cut connection
            pass
        assert r is None or r.isError()
        c.close()
    finally:
        srv.down()


def test_command_serves_and_prints_counts(tmp_path):
    out = tmp_path / "e.jsonl"
    p = subprocess.Popen([sys.executable, "-m", "mippeer.unicos", "--port", "0", "--pair", "0",
                          "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        m = re.match(r"mip-peer-unicos: listening A=(\d+) B=(\d+)", p.stdout.readline())
        assert m
        assert not _write(int(m.group(2)), [0x1201, 7, 1] + t3(T)).isError()
        p.send_signal(signal.SIGUSR1)               # driver A down
        assert p.stdout.readline().strip() == "mip-peer-unicos: driver A down"
        p.terminate()
        assert p.wait(timeout=10) == 0
        assert p.stdout.read().strip() == ("mip-peer-unicos: done A:frames=0,events=0,duplicates=0,"
                                           "refused=0 B:frames=1,events=1,duplicates=0,refused=0")
        assert json.loads(out.read_text())["driver"] == "B"
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        p.stdout.close()
        p.stderr.close()


@pytest.mark.parametrize("args,msg", [
    (["--marker", "0x10000"], "mip-peer-unicos: error: --marker must be 0..0xFFFF"),
    (["--port", "70000"], "mip-peer-unicos: error: ports are 0..65535"),
    (["--out", "/nonexistent/dir/e.jsonl", "--port", "0"],
     "mip-peer-unicos: error: [Errno 2] No such file or directory: '/nonexistent/dir/e.jsonl'"),
])
def test_command_errors_are_one_line(args, msg):
    p = subprocess.run([sys.executable, "-m", "mippeer.unicos", *args], capture_output=True,
                       text=True, timeout=30)
    assert p.returncode == 2
    assert p.stderr.strip() == msg


def test_utc_text():
    assert ticks_to_utc(0) == "1970-01-01T00:00:00.000Z"
    assert ticks_to_utc(T + 99) == "2026-01-01T00:00:00.990Z"


def test_mip_peer_unicos_is_the_same_command():
    p = subprocess.run([sys.executable, "-m", "mippeer.cli", "unicos", "--marker", "-1"],
                       capture_output=True, text=True, timeout=30)
    assert p.returncode == 2
    assert p.stderr.strip() == "mip-peer-unicos: error: --marker must be 0..0xFFFF"
