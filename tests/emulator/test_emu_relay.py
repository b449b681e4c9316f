"""The real-time SIPROTEC event recorder (mip-emulator --relay) against a pymodbus master doing
the SOE_Control handshake: what a master sees, as docs/chain.md "The relay" describes it."""
import socket
import struct

import pytest

from miptest.emu import connect, run_cli, wait_until
from relay_support import BASE, ORIGIN_MS, Master, RelayServer, exc, write_script

EVENTS = [(k / 1000, 0x0102, 100 + k, 0x0101, k) for k in range(1, 8)]  # 7 events at k ms


@pytest.fixture
def relay(tmp_path, request):
    servers = []

    def start(opts="", events=EVENTS):
        script = write_script(tmp_path / "events.txt", events)
        s = RelayServer(f"script={script}" + ("," + opts if opts else ""))
        servers.append(s)
        m = Master(s.port)
        request.addfinalizer(m.close)
        # the scripted times are since the server's start: wait until all have happened
        s.sleep_past(max(e[0] for e in events))
        assert wait_until(lambda: m.count() >= min(len(events), 5), timeout=10)
        return m

    yield start
    for s in servers:
        assert s.stop() == 0


def test_handshake_takes_every_event_once_in_order_with_its_time_stamp(relay):
    m = relay()
    entries, seq, blocks, _ = m.read()
    assert entries == 7 and seq == 1 and len(blocks) == 3   # at most 3 blocks a read
    assert m.ack(seq, 3) == 0
    entries, seq2, blocks2, _ = m.read()
    assert entries == 4 and seq2 == 2                          # deleted, sequence number raised
    assert [b["value"] for b in blocks2] == [4, 5, 6]
    got = blocks + blocks2
    assert m.ack(seq2, 3) == 0
    got += m.drain()
    assert [b["value"] for b in got] == list(range(1, 8))
    assert [b["addr"] for b in got] == [100 + k for k in range(1, 8)]
    assert [b["ts_ms"] for b in got] == [ORIGIN_MS + k for k in range(1, 8)]
    assert all(b["type_bit"] == 0x0102 and b["cause_type"] == 0x0101 for b in got)
    entries, _, blocks, _ = m.read()
    assert entries == 0 and blocks == []


def test_a_failed_read_repeated_gives_the_same_data(relay):
    m = relay()
    _, _, _, first = m.read()
    # the master lost the answer (say a CRC error) and reads again: nothing was acknowledged
    _, _, _, again = m.read()
    assert again == first
    # a new master connection (the old one died) sees the same too
    m2 = Master(m.c.comm_params.port)
    try:
        assert m2.read()[3] == first
    finally:
        m2.close()


def test_partial_acknowledgement_offers_the_rest_again(relay):
    m = relay()
    _, seq, blocks, _ = m.read()
    assert m.ack(seq, 1) == 0
    entries, seq2, blocks2, _ = m.read()
    assert entries == 6 and seq2 == seq + 1
    assert [b["value"] for b in blocks2] == [2, 3, 4]


def test_reset_list_with_the_acknowledgement_and_alone(relay):
    m = relay()
    _, seq, _, _ = m.read()
    assert m.ack(seq, 3, reset=True) == 0
    entries, seq_after, blocks, raw = m.read()
    assert entries == 0 and blocks == [] and seq_after == seq   # the number is not reset
    assert raw[1] & 0xC000 == 0                                  # bits 14 and 15 read as 0


def test_reset_list_by_writing_sequence_number_0(tmp_path):
    events = [(0.001, 1, 1, 1, 1), (0.002, 1, 1, 1, 2), (0.5, 1, 1, 1, 3)]
    s = RelayServer(f"script={write_script(tmp_path / 'e.txt', events)}")
    m = Master(s.port)
    try:
        assert wait_until(lambda: m.count() == 2, timeout=10)
        _, seq, _, _ = m.read()
        assert m.ack(0, 0, reset=True) == 0
        assert m.read()[0] == 0
        # the next entry comes with the next (raised) sequence number
        assert wait_until(lambda: m.read()[0] == 1, timeout=10)
        _, seq_next, blocks, _ = m.read()
        assert seq_next == seq + 1 and blocks[0]["value"] == 3
    finally:
        m.close()
        assert s.stop() == 0


@pytest.mark.parametrize("overflow,kept", [("drop-oldest", [1, 2, 3, 6, 7]),
                                           ("drop-new", [1, 2, 3, 4, 5])])
def test_overflow(relay, overflow, kept):
    m = relay(f"cap=5,overflow={overflow}")
    assert m.read()[0] == 5
    assert [b["value"] for b in m.drain()] == kept


def test_bad_writes_are_answered_and_change_nothing(relay):
    m = relay()
    _, seq, _, before = m.read()
    assert m.ack(seq + 1, 3) == 3                        # wrong sequence number
    assert m.ack(seq, 4) == 3                            # more than offered
    assert m.ack(0, 1) == 3                              # sequence number 0 without reset
    assert exc(m.c.write_register(BASE, 0)) == 3         # read-only: the count
    assert exc(m.c.write_register(BASE + 5, 0)) == 3     # read-only: a message block
    assert exc(m.c.write_registers(BASE + 1, [seq | 3 << 8, 0])) == 3
    assert exc(m.c.write_register(BASE + 26, 0)) == 2    # outside the map
    assert exc(m.c.read_holding_registers(BASE + 20, count=7)) == 2
    assert exc(m.c.read_input_registers(BASE, count=2)) == 1
    assert m.read()[3] == before
    # an acknowledgement repeated after its answer was lost: refused, nothing more deleted
    assert m.ack(seq, 3) == 0
    assert m.ack(seq, 3) == 3
    assert m.read()[0] == 4


def test_bad_acknowledgement_ignored_when_configured(relay):
    m = relay("bad-ack=ignore")
    _, seq, _, before = m.read()
    assert m.ack(seq + 1, 3) == 0
    assert m.read()[3] == before


def test_address_base_is_configurable(tmp_path):
    s = RelayServer(f"base=0,script={write_script(tmp_path / 'e.txt', EVENTS)}")
    m = Master(s.port, base=0)
    try:
        assert wait_until(lambda: m.count() == 7, timeout=10)
        assert [b["value"] for b in m.drain()] == list(range(1, 8))
    finally:
        m.close()
        assert s.stop() == 0


def test_generated_events_at_a_rate():
    s = RelayServer("rate=200")
    m = Master(s.port)
    try:
        assert wait_until(lambda: m.read()[0] >= 5, timeout=20)
        got = m.drain()
        assert [b["value"] for b in got[:5]] == [1, 2, 3, 4, 5]
        assert got[0]["ts_ms"] == ORIGIN_MS + 5      # the first at 1/200 s
    finally:
        m.close()
        assert s.stop() == 0


@pytest.mark.parametrize("spec,msg", [
    ("0:cap=2", "--relay cap"),
    ("0:overflow=wrap", "overflow"),
    ("0:colour=red", "unknown key 'colour'"),
    ("0:burst=3", "N/SECONDS"),
    ("0:script=/nonexistent/x", "script=/nonexistent/x"),
])
def test_bad_relay_options_one_line(spec, msg):
    p = run_cli("--relay", spec)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mip-emulator: error:") and msg in lines[0], p.stderr


def test_blocks_read_stay_unchanged_while_new_events_arrive(tmp_path):
    events = [(0.001, 1, 1, 1, 1), (0.6, 1, 1, 1, 2)]
    s = RelayServer(f"script={write_script(tmp_path / 'e.txt', events)}")
    m = Master(s.port)
    try:
        s.sleep_past(0.001, margin=0.1)
        _, seq, blocks, first = m.read()
        assert [b["value"] for b in blocks] == [1]
        s.sleep_past(0.6)
        entries, _, _, now = m.read()
        assert entries == 2                       # the count shows the newcomer ...
        assert now[1:] == first[1:]               # ... SOE_Control and the blocks do not
        assert m.ack(seq, 1) == 0
        _, seq2, blocks, _ = m.read()
        assert seq2 == seq + 1 and [b["value"] for b in blocks] == [2]
    finally:
        m.close()
        assert s.stop() == 0


def raw(sock, adu):
    sock.sendall(adu)
    head = sock.recv(7, socket.MSG_WAITALL)
    if not head:
        return None
    n = struct.unpack(">H", head[4:6])[0]
    return head + sock.recv(n - 1, socket.MSG_WAITALL)


def test_hostile_frames_close_only_their_connection(relay):
    m = relay()
    before = m.read()[3]
    port = m.c.comm_params.port
    a, b = connect(port), connect(port)
    try:
        # a PDU too short for FC3 and an FC16 whose byte count lies: exception 03, connection stays
        assert raw(a, struct.pack(">HHHB", 1, 0, 4, 1) + bytes([3, 2, 88])) == \
            struct.pack(">HHHB", 1, 0, 3, 1) + bytes([0x83, 3])
        assert raw(a, struct.pack(">HHHB", 2, 0, 10, 1) + bytes([16, 2, 89, 0, 1, 4, 1, 3, 0, 0])) == \
            struct.pack(">HHHB", 2, 0, 3, 1) + bytes([0x90, 3])
        # protocol id 1: not Modbus, the connection closes
        a.sendall(struct.pack(">HHHB", 3, 1, 6, 1) + bytes([3, 2, 88, 0, 26]))
        a.settimeout(10)
        assert a.recv(100) == b""
        # the other connection and the recorder are untouched
        r = raw(b, struct.pack(">HHHB", 4, 0, 6, 7) + bytes([3, 2, 88, 0, 26]))
        assert r[6] == 7 and list(struct.unpack(">26H", r[9:])) == before
    finally:
        a.close()
        b.close()
