"""The server front: framing, pipelining, malformed frames, many clients, CLI, trace file.

Raw sockets here only where a conformant client cannot produce the bytes."""
import resource
import socket
import struct
import subprocess

import pytest
from pymodbus.client import ModbusTcpClient

from miptest.emu import (BINARY, FAST, Emulator, closed_by_peer, connect, frame, recv_frame,
                         run_cli, wait_until)


@pytest.fixture
def emu(tmp_path):
    e = Emulator("--stations", 2, *FAST, trace=tmp_path / "trace.jsonl")
    yield e
    assert e.stop() == 0


def read_pdu(addr, n, fc=3):
    return struct.pack(">BHH", fc, addr, n)


def fc16_pdu(addr, values):
    # the byte count is one byte: 128 registers wrap it (a frame no client should send)
    return struct.pack(">BHHB", 16, addr, len(values), 2 * len(values) & 0xFF) + b"".join(
        struct.pack(">H", v) for v in values)


def fc23_pdu(ra, rq, wa, values):
    return struct.pack(">BHHHHB", 23, ra, rq, wa, len(values), 2 * len(values)) + b"".join(
        struct.pack(">H", v) for v in values)


def still_serves(emu):
    c = ModbusTcpClient("127.0.0.1", port=emu.mdp_port, timeout=5, retries=0)
    assert c.connect()
    r = c.read_holding_registers(2, count=1, device_id=1)
    c.close()
    return not r.isError()


def test_pipelined_requests_all_answered_in_order(emu):
    s = connect(emu.mdp_port)
    reqs = [
        frame(1, 1, read_pdu(2, 1)),
        frame(2, 1, bytes([1, 0, 0, 0, 1])),          # FC1: exception 01, must not drop what follows
        frame(3, 1, read_pdu(3, 1)),                  # exception 02
        frame(4, 1, fc16_pdu(10, [0] * 124)),         # exception 03
        frame(5, 9, read_pdu(0, 1)),                  # exception 0B
        frame(6, 2, fc16_pdu(10, [1, 2, 3])),
        frame(7, 2, read_pdu(9, 4)),
    ]
    s.sendall(b"".join(reqs))
    answers = [recv_frame(s) for _ in reqs]
    assert [a[0] for a in answers] == [1, 2, 3, 4, 5, 6, 7]
    assert [a[1] for a in answers] == [1, 1, 1, 1, 9, 2, 2]
    assert answers[0][2] == bytes([3, 2, 0, 0])
    assert answers[1][2] == bytes([0x81, 1])
    assert answers[2][2] == bytes([0x83, 2])
    assert answers[3][2] == bytes([0x90, 3])
    assert answers[4][2] == bytes([0x83, 0x0B])
    assert answers[5][2] == bytes([16, 0, 10, 0, 3])
    assert answers[6][2] == bytes([3, 8, 0, 3, 0, 1, 0, 2, 0, 3])
    s.close()


def test_frame_in_pieces(emu):
    s = connect(emu.trm_port(1))
    f = frame(0x1234, 1, read_pdu(2000, 2))
    for b in f:
        s.sendall(bytes([b]))
    assert recv_frame(s) == (0x1234, 1, bytes([3, 4, 0, 0, 0, 0]))
    s.close()


def test_oversized_frames_read_whole_and_answered_03(emu):
    s = connect(emu.trm_port(1))
    # FC16 of 127 registers: a 267-byte frame, beyond the standard 260
    s.sendall(frame(1, 1, fc16_pdu(2001, list(range(127)))))
    assert recv_frame(s) == (1, 1, bytes([0x90, 3]))
    s.sendall(frame(2, 1, fc23_pdu(2198, 125, 2001, [0] * 122)))
    assert recv_frame(s) == (2, 1, bytes([0x97, 3]))
    s.sendall(frame(3, 1, fc23_pdu(2198, 126, 2001, [0])))
    assert recv_frame(s) == (3, 1, bytes([0x97, 3]))
    # a byte count that disagrees with the quantity, a PDU too short for its function
    s.sendall(frame(4, 1, struct.pack(">BHHB", 16, 2001, 2, 2) + b"\0\0"))
    assert recv_frame(s) == (4, 1, bytes([0x90, 3]))
    s.sendall(frame(5, 1, bytes([3, 0x07])))
    assert recv_frame(s) == (5, 1, bytes([0x83, 3]))
    # and the connection is still good; nothing of the rejected writes arrived
    s.sendall(frame(6, 1, read_pdu(2000, 1)))
    assert recv_frame(s) == (6, 1, bytes([3, 2, 0, 0]))
    s.close()


def test_allow_127_read_and_fc23(tmp_path):
    e = Emulator("--allow-127", *FAST)
    try:
        s = connect(e.trm_port(1))
        s.sendall(frame(1, 1, fc23_pdu(2198, 127, 2001, list(range(127)))))
        tid, unit, pdu = recv_frame(s)
        assert pdu[:2] == bytes([23, 254])
        assert struct.unpack(">H", pdu[4:6])[0] == 0  # 2199: nothing received yet
        s.sendall(frame(2, 1, fc16_pdu(2001, [0] * 128)))
        assert recv_frame(s) == (2, 1, bytes([0x90, 3]))
        s.close()
    finally:
        assert e.stop() == 0


@pytest.mark.parametrize("bad", [
    frame(1, 1, read_pdu(2, 1), proto=1),             # protocol id not Modbus
    frame(1, 1, b"", length=1),                       # no function code
    frame(1, 1, b"", length=0),
    struct.pack(">HHHB", 1, 0, 0xFFFF, 1) + b"\3" * 100,  # length beyond any Modbus frame
])
def test_malformed_frame_closes_that_connection_only(emu, bad):
    bystander = connect(emu.mdp_port)
    victim = connect(emu.mdp_port)
    victim.sendall(bad)
    assert closed_by_peer(victim)
    victim.close()
    bystander.sendall(frame(9, 1, read_pdu(2, 1)))
    assert recv_frame(bystander) == (9, 1, bytes([3, 2, 0, 0]))
    bystander.close()
    assert still_serves(emu)
    assert emu.alive()


def test_answers_before_a_malformed_frame_still_go_out(emu):
    s = connect(emu.mdp_port)
    s.sendall(frame(1, 1, read_pdu(2, 1)) + frame(2, 1, read_pdu(2, 1), proto=7))
    assert recv_frame(s) == (1, 1, bytes([3, 2, 0, 0]))
    assert closed_by_peer(s)
    s.close()
    assert emu.stop() == 0
    mb = [x for x in emu.trace() if x["ev"] == "modbus"]
    assert mb[0]["tid"] == 1 and mb[0]["exc"] == 0
    assert mb[1]["close"] == "malformed frame" and mb[1]["ep"] == "mdp" and mb[1]["len"] == 12


def test_half_closed_client_still_gets_its_answers(emu):
    s = connect(emu.mdp_port)
    s.sendall(b"".join(frame(i, 1, read_pdu(198, 100)) for i in range(20)))
    s.shutdown(socket.SHUT_WR)
    assert [recv_frame(s)[0] for _ in range(20)] == list(range(20))
    assert closed_by_peer(s)
    s.close()


def test_client_that_never_reads_does_not_block_others(emu):
    hog = connect(emu.mdp_port)
    hog.setblocking(False)
    req = frame(1, 1, read_pdu(198, 125)) * 1000   # 12 kB in, 257 kB of answers out
    sent = 0
    for _ in range(200):                           # as much as the kernel takes, never reading
        try:
            sent += hog.send(req)
        except BlockingIOError:
            break
    assert sent > 0
    for _ in range(3):
        assert still_serves(emu)
    hog.close()
    assert still_serves(emu)


def test_client_that_vanishes_mid_frame(emu):
    s = connect(emu.mdp_port)
    s.sendall(frame(1, 1, fc16_pdu(10, [1] * 50))[:30])
    s.close()
    assert still_serves(emu)


def test_200_concurrent_clients(emu):
    socks = []
    for i in range(200):
        socks.append(connect(emu.mdp_port if i % 2 else emu.trm_port(1 + i % 4 // 2)))
    # all connected at once; each asks, each gets its own answer
    for i, s in enumerate(socks):
        addr = 2 if i % 2 else 2198
        s.sendall(frame(i, 1, read_pdu(addr, 1)))
    for i, s in enumerate(socks):
        assert recv_frame(s) == (i, 1, bytes([3, 2, 0, 0]))
    for s in socks:
        s.close()
    assert still_serves(emu)


def test_descriptors_beyond_1024(emu):
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = 1300
    if hard != resource.RLIM_INFINITY and hard < want:
        pytest.skip(f"the hard descriptor limit {hard} is below {want}: cannot open that many sockets")
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, want), hard))
    socks = []
    try:
        for _ in range(1100):
            socks.append(connect(emu.mdp_port))
        # the server's own descriptors for these are above 1024 now; the last ones must work
        for i, s in enumerate(socks[-50:]):
            s.sendall(frame(i, 1, read_pdu(2, 1)))
            assert recv_frame(s) == (i, 1, bytes([3, 2, 0, 0]))
    finally:
        for s in socks:
            s.close()
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    assert still_serves(emu)


def test_out_of_descriptors_sheds_clients_and_recovers():
    def low_limit():
        resource.setrlimit(resource.RLIMIT_NOFILE, (40, 40))

    e = Emulator(*FAST, preexec_fn=low_limit)
    try:
        socks = [connect(e.mdp_port) for _ in range(60)]   # more than the server can hold
        answered = refused = 0
        for i, s in enumerate(socks):
            try:
                s.sendall(frame(i, 1, read_pdu(2, 1)))
                assert recv_frame(s) == (i, 1, bytes([3, 2, 0, 0]))
                answered += 1
            except (ConnectionError, OSError):
                refused += 1
        assert answered >= 20 and refused >= 10, (answered, refused)
        for s in socks:
            s.close()
        assert wait_until(lambda: still_serves(e))
        assert e.alive()
    finally:
        assert e.stop() == 0


def test_trace_file_lines(tmp_path):
    e = Emulator("--stations", 2, *FAST, trace=tmp_path / "t.jsonl")
    c = ModbusTcpClient("127.0.0.1", port=e.trm_port(2), timeout=5, retries=0)
    assert c.connect()
    c.write_registers(2001, [42, 1, 2])
    c.read_holding_registers(3000, count=1)
    m = ModbusTcpClient("127.0.0.1", port=e.mdp_port, timeout=5, retries=0)
    assert m.connect()
    assert wait_until(lambda: m.read_holding_registers(199, count=1, device_id=2).registers == [3])
    # the ack telegram that confirms the block (read-status bit 4 clears), which the trace
    # must show too: the answer alone may be all there is when the machine is busy
    assert wait_until(lambda: c.read_holding_registers(2198, count=1).registers[0] & 0x10 == 0)
    c.close()
    m.close()
    assert e.stop() == 0
    lines = e.trace()
    ts = [x["t"] for x in lines]
    assert ts == sorted(ts)                       # virtual time never goes back
    assert [x["seq"] for x in lines] == list(range(len(lines)))
    mb = [x for x in lines if x["ev"] == "modbus"]
    assert {"ep": "trm", "st": 2, "fc": 16, "wa": 2001, "wq": 3, "w0": 42, "exc": 0}.items() <= mb[0].items()
    assert {"ep": "trm", "st": 2, "fc": 3, "ra": 3000, "rq": 1, "exc": 2}.items() <= mb[1].items()
    up = [x for x in lines if x["ev"] == "radio" and x["dir"] == "up" and x["regs"] == 3]
    assert up and up[0]["st"] == 2 and up[0]["r0"] == 42 and up[0]["lost"] is False
    assert up[0]["bytes"] == 12 + 6 and up[0]["t"] > up[0]["t0"]
    radio = [x for x in lines if x["ev"] == "radio"]
    assert {x["kind"] for x in radio} == {"poll", "answer", "ack"}
    assert {x["st"] for x in radio} == {1, 2}


# ---- CLI ----

def test_help_documents_every_option():
    r = run_cli("--help")
    assert r.returncode == 0
    for opt in ("--host", "--mdp-port", "--trm-base-port", "--stations", "--mode", "--static-registers",
                "--loss-down", "--loss-up", "--burst", "--seed", "--bitrate", "--slot-gap-ms",
                "--overhead-bytes", "--fail-polls", "--allow-127", "--trace", "--help"):
        assert opt in r.stdout, opt


def test_help_puts_each_default_under_its_option():
    lines = run_cli("--help").stdout.splitlines()
    i = next(k for k, t in enumerate(lines) if t.lstrip().startswith("--allow-127"))
    assert "default: the Modbus limits 125 read" in lines[i + 1]
    j = next(k for k, t in enumerate(lines) if t.lstrip().startswith("--lose-record"))
    block = lines[j:next(k for k in range(j + 1, len(lines)) if lines[k].lstrip().startswith("--"))]
    assert "default off" in " ".join(block) and "125" not in " ".join(block)


@pytest.mark.parametrize("args", [
    ["--bogus"], ["--stations", "0"], ["--stations", "248"], ["--stations", "x"], ["--mode", "fast"],
    ["--static-registers", "149"], ["--loss-up", "1.5"], ["--loss-down", "-0.1"], ["--loss-up"],
    ["--burst", "0.5"], ["--seed", "-1"], ["--bitrate", "0"], ["--slot-gap-ms", "abc"],
    ["--mdp-port", "70000"], ["--host", "localhost"], ["stray"],
    ["--trm-base-port", "65535", "--stations", "3"],
])
def test_bad_options_one_line_exit_2(args):
    r = run_cli(*args)
    assert r.returncode == 2
    assert r.stdout == ""
    assert len(r.stderr.strip().splitlines()) == 1
    assert r.stderr.startswith("mip-emulator: error: ")


def test_port_in_use_is_one_line_error():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    port = s.getsockname()[1]
    r = run_cli("--mdp-port", port, "--trm-base-port", 0)
    s.close()
    assert r.returncode != 0
    assert len(r.stderr.strip().splitlines()) == 1 and "cannot listen" in r.stderr


def free_port_pair():
    """A port p such that p and p+1 could both be bound just now."""
    for _ in range(50):
        a = socket.socket()
        a.bind(("127.0.0.1", 0))
        base = a.getsockname()[1]
        b = socket.socket()
        try:
            b.bind(("127.0.0.1", base + 1))
            return base
        except OSError:
            continue
        finally:
            a.close()
            b.close()
    return None


def test_fixed_ports():
    for _ in range(5):
        base = free_port_pair()
        assert base is not None, "no two neighbouring free ports found on 127.0.0.1"
        proc = subprocess.Popen([str(BINARY), "--mdp-port", "0", "--trm-base-port", str(base),
                                 "--stations", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = proc.stdout.readline()
        proc.terminate()
        proc.wait(timeout=10)
        proc.stdout.close()
        err = proc.stderr.read()
        proc.stderr.close()
        if line:
            break
        assert "Address already in use" in err  # another process took it meanwhile: try again
    assert line.strip().endswith(f"trm={base},{base + 1}")
    assert proc.returncode == 0
