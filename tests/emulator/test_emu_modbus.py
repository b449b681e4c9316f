"""The emulator's Modbus side, from mip-protocol.md §2-3, through pymodbus against the real server."""
import pytest
from pymodbus.client import ModbusTcpClient

from miptest.emu import FAST, Emulator, wait_until

STATIONS = 3


@pytest.fixture
def emu(tmp_path):
    e = Emulator("--stations", STATIONS, *FAST, trace=tmp_path / "trace.jsonl")
    yield e
    assert e.stop() == 0


@pytest.fixture
def slow_emu(tmp_path):
    # a slow radio: 12-byte empty telegrams take 320 ms at 300 bit/s, plus 2 s gaps, so station 2
    # is first polled 4.6 s after the start
    e = Emulator("--stations", 2, "--bitrate", 300, "--slot-gap-ms", 2000, trace=tmp_path / "trace.jsonl")
    yield e
    assert e.stop() == 0


def client(port):
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=5, retries=0)
    assert c.connect()
    return c


def exc(r):
    """The exception code of a response, 0 for a normal response."""
    return r.exception_code if r.isError() else 0


def mdp_reg(c, unit, addr):
    r = c.read_holding_registers(addr, count=1, device_id=unit)
    assert not r.isError(), r
    return r.registers[0]


# ---- register maps ----

TRM_READABLE = [(2000, 1), (2000, 125), (2024, 125), (2148, 1), (2198, 125), (2223, 125), (2347, 1)]
TRM_OUTSIDE = [(0, 1), (1999, 1), (1999, 2), (2148, 2), (2149, 1), (2197, 1), (2197, 2), (2348, 1), (2340, 10),
               (2025, 125)]
MDP_READABLE = [(0, 1), (0, 3), (4, 1), (9, 1), (9, 125), (33, 125), (157, 1), (198, 125), (223, 125), (347, 1)]
MDP_OUTSIDE = [(3, 1), (0, 4), (2, 3), (5, 1), (6, 1), (7, 1), (8, 1), (8, 2), (158, 1), (167, 1), (168, 1),
               (197, 1), (197, 2), (348, 1), (340, 10), (1000, 1), (2000, 1)]


@pytest.mark.parametrize("fc", [3, 4])
def test_trm_map_boundaries(emu, fc):
    c = client(emu.trm_port(1))
    read = c.read_holding_registers if fc == 3 else c.read_input_registers
    for addr, n in TRM_READABLE:
        r = read(addr, count=n)
        assert exc(r) == 0, (addr, n)
        assert len(r.registers) == n
    for addr, n in TRM_OUTSIDE:
        assert exc(read(addr, count=n)) == 2, (addr, n)
    c.close()


@pytest.mark.parametrize("fc", [3, 4])
def test_mdp_map_boundaries(emu, fc):
    c = client(emu.mdp_port)
    read = c.read_holding_registers if fc == 3 else c.read_input_registers
    for addr, n in MDP_READABLE:
        r = read(addr, count=n, device_id=2)
        assert exc(r) == 0, (addr, n)
        assert len(r.registers) == n
    for addr, n in MDP_OUTSIDE:
        assert exc(read(addr, count=n, device_id=2)) == 2, (addr, n)
    c.close()


def test_read_only_registers_reject_writes(emu):
    t = client(emu.trm_port(1))
    for addr in (2000, 2198, 2199, 2200, 2347):
        assert exc(t.write_registers(addr, [1])) == 2, addr
    assert exc(t.write_registers(2147, [1, 2, 3])) == 2  # runs past the write area
    m = client(emu.mdp_port)
    for addr in (0, 1, 2, 4, 9, 198, 199, 200, 347):
        assert exc(m.write_register(addr, 1, device_id=1)) == 2, addr
        assert exc(m.write_registers(addr, [1], device_id=1)) == 2, addr
    assert exc(m.write_registers(9, [1, 2], device_id=1)) == 2  # starts on the read-only count
    assert exc(m.write_registers(157, [1, 2], device_id=1)) == 2  # 158 is reserved
    # nothing was changed by the rejected writes
    assert mdp_reg(m, 1, 9) == 0
    assert t.read_holding_registers(2000, count=1).registers == [0]
    t.close()
    m.close()


def test_quantity_limits_exception_03(emu):
    t = client(emu.trm_port(1))
    assert exc(t.read_holding_registers(2200, count=125)) == 0
    assert exc(t.write_registers(2001, [0] * 123)) == 0
    assert exc(t.write_registers(2001, [0] * 124)) == 3
    assert exc(t.write_registers(2001, [0] * 127)) == 3  # a 267-byte frame, read whole, answered
    assert exc(t.readwrite_registers(read_address=2198, read_count=125, write_address=2001,
                                     values=[0] * 121)) == 0
    # FC23 beyond 121/125: pymodbus refuses to send it; test_emu_server.py sends it raw
    # quantity is checked before the address (Modbus order): 03 even outside the map
    assert exc(t.write_registers(3000, [0] * 124)) == 3
    # the connection survived all of that
    assert exc(t.read_holding_registers(2000, count=1)) == 0
    t.close()


def test_allow_127_accepts_the_devices_limit(tmp_path):
    e = Emulator("--allow-127", *FAST)
    try:
        t = client(e.trm_port(1))
        assert exc(t.write_registers(2001, list(range(127)))) == 0
        m = client(e.mdp_port)
        assert wait_until(lambda: mdp_reg(m, 1, 4) == 127)
        assert m.read_holding_registers(200, count=125, device_id=1).registers == list(range(125))
        t.close()
        m.close()
    finally:
        assert e.stop() == 0


def test_unsupported_function_codes_exception_01(emu):
    m = client(emu.mdp_port)
    assert exc(m.read_coils(0, count=1, device_id=1)) == 1
    assert exc(m.read_discrete_inputs(0, count=1, device_id=1)) == 1
    assert exc(m.write_coil(0, True, device_id=1)) == 1
    assert exc(m.write_coils(0, [True, False], device_id=1)) == 1
    assert exc(m.mask_write_register(address=10, and_mask=0xFF, or_mask=0, device_id=1)) == 1
    t = client(emu.trm_port(2))
    assert exc(t.read_coils(0, count=1)) == 1
    assert exc(t.read_holding_registers(2000, count=1)) == 0
    m.close()
    t.close()


# ---- stations ----

def test_unit_id_selects_station_and_unknown_gets_0B(emu):
    m = client(emu.mdp_port)
    for unit in (0, STATIONS + 1, 100, 247, 255):
        assert exc(m.read_holding_registers(0, count=1, device_id=unit)) == 0x0B, unit
        assert exc(m.write_registers(10, [1], device_id=unit)) == 0x0B, unit
    # a block for station 2 reaches TRM 2 only
    assert exc(m.write_registers(10, [22, 23], device_id=2)) == 0
    trms = {s: client(emu.trm_port(s)) for s in range(1, STATIONS + 1)}
    assert wait_until(lambda: trms[2].read_holding_registers(2198, count=4).registers == [1, 2, 22, 23])
    for s in (1, 3):
        assert trms[s].read_holding_registers(2198, count=2).registers == [0, 0]
    # and back: station 3's block appears under unit 3 only
    assert exc(trms[3].write_registers(2001, [33])) == 0
    assert wait_until(lambda: m.read_holding_registers(198, count=3, device_id=3).registers == [1, 1, 33])
    assert m.read_holding_registers(198, count=2, device_id=1).registers == [0, 0]
    assert m.read_holding_registers(198, count=2, device_id=2).registers == [0, 0]
    m.close()
    for c in trms.values():
        c.close()


def test_trm_ignores_unit_id(emu):
    t = client(emu.trm_port(1))
    for unit in (0, 1, 7, 255):
        r = t.read_holding_registers(2000, count=1, device_id=unit)
        assert exc(r) == 0 and r.dev_id == unit
    t.close()


def test_station_status_and_field_strength(emu):
    m = client(emu.mdp_port)
    # every station answers its polls on a lossless link: bits 0 (answered) and 2 (ever answered)
    for s in range(1, STATIONS + 1):
        assert wait_until(lambda: mdp_reg(m, s, 1) == 0b101), s
        fs = mdp_reg(m, s, 0)
        assert 40 <= fs >> 8 <= 120 and 40 <= fs & 0xFF <= 120, hex(fs)
    m.close()


def test_unreachable_station_status(tmp_path):
    e = Emulator("--loss-down", 1, "--fail-polls", 2, *FAST)
    try:
        m = client(e.mdp_port)
        assert wait_until(lambda: mdp_reg(m, 1, 1) == 0b010)
        assert mdp_reg(m, 1, 0) == 0  # never heard: no field strength
        m.close()
    finally:
        assert e.stop() == 0


# ---- dynamic transfer ----

def test_dynamic_write_rules(emu):
    t = client(emu.trm_port(1))
    assert exc(t.write_registers(2002, [1, 2])) == 2      # not at the first write register
    assert exc(t.write_register(2001, 5)) == 2            # FC6 is not a block write
    assert exc(t.readwrite_registers(read_address=2000, read_count=1, write_address=2005,
                                     values=[1])) == 2
    assert t.read_holding_registers(2000, count=1).registers == [0]
    m = client(emu.mdp_port)
    assert exc(m.write_registers(11, [1], device_id=1)) == 2
    assert exc(m.write_register(10, 1, device_id=1)) == 2
    t.close()
    m.close()


def test_dynamic_transfer_status_bits_and_count(emu):
    t = client(emu.trm_port(1))
    m = client(emu.mdp_port)
    payload = [1] + list(range(100, 140))
    r = t.write_registers(2001, payload)
    assert exc(r) == 0
    # the receiver gets it: new-data bit, count, data, copies at 198/199
    assert wait_until(lambda: mdp_reg(m, 1, 2) & 1 == 1)
    assert mdp_reg(m, 1, 4) == len(payload)
    assert m.read_holding_registers(198, count=2, device_id=1).registers[1] == len(payload)
    # the sender: waiting (bit 1) and unconfirmed (bit 4) clear once confirmed, count back to 0
    assert wait_until(lambda: t.read_holding_registers(2198, count=1).registers[0] & 0x12 == 0)
    assert wait_until(lambda: t.read_holding_registers(2000, count=1).registers == [0])
    # reading status and count alone clears nothing
    assert m.read_holding_registers(198, count=2, device_id=1).registers == [1, len(payload)]
    assert m.read_holding_registers(2, count=1, device_id=1).registers == [1]
    # one consistent read of status, count and data: the response still shows the bit ...
    r = m.read_holding_registers(198, count=2 + len(payload), device_id=1)
    assert r.registers == [1, len(payload)] + payload
    # ... and afterwards it is clear
    assert mdp_reg(m, 1, 2) & 1 == 0
    assert mdp_reg(m, 1, 198) & 1 == 0
    t.close()
    m.close()


def test_dynamic_write_sets_count_and_bits_1_and_4(emu):
    # FC23 writes then reads in one atomic request, so the read shows the state right after the
    # write, before any radio slot could send it
    t = client(emu.trm_port(2))
    r = t.readwrite_registers(read_address=2000, read_count=1, write_address=2001, values=[5, 6, 7])
    assert r.registers == [3]
    r = t.readwrite_registers(read_address=2198, read_count=1, write_address=2001, values=[5, 6])
    assert r.registers == [0x12]
    t.close()


def test_second_write_before_transmission_replaces_the_first(slow_emu):
    m = client(slow_emu.mdp_port)
    t = client(slow_emu.trm_port(2))
    assert exc(m.write_registers(10, [1, 11, 12, 13], device_id=2)) == 0
    assert exc(m.write_registers(10, [2, 21], device_id=2)) == 0
    assert mdp_reg(m, 2, 9) == 2
    assert wait_until(lambda: t.read_holding_registers(2198, count=1).registers[0] & 1 == 1, timeout=30)
    assert t.read_holding_registers(2198, count=4).registers == [1, 2, 2, 21]
    assert wait_until(lambda: mdp_reg(m, 2, 2) & 0x12 == 0, timeout=30)
    down = [x for x in slow_emu.trace() if x["ev"] == "radio" and x["kind"] == "poll" and x["st"] == 2
            and x["regs"] > 0]
    assert [(x["regs"], x["r0"]) for x in down] == [(2, 2)]  # the first block never went on air
    m.close()
    t.close()


def test_unread_data_are_overwritten(emu):
    m = client(emu.mdp_port)
    t = client(emu.trm_port(1))
    for block in ([1, 10, 11, 12], [2, 20]):
        assert exc(m.write_registers(10, block, device_id=1)) == 0
        assert wait_until(lambda: mdp_reg(m, 1, 2) & 0x10 == 0)
    # never read in between: the second block replaced the first, the bit is set
    r = t.read_holding_registers(2198, count=6).registers
    assert r[:4] == [1, 2, 2, 20]
    assert r[4:] == [11, 12]  # beyond the new count the old registers stay (documented)
    assert t.read_holding_registers(2198, count=1).registers == [0]
    m.close()
    t.close()


def test_fc23_writes_then_reads_in_one_request(emu):
    t = client(emu.trm_port(1))
    r = t.readwrite_registers(read_address=2000, read_count=4, write_address=2001, values=[7, 8, 9])
    assert exc(r) == 0
    assert r.registers == [3, 7, 8, 9]  # the read sees the write: count and data
    m = client(emu.mdp_port)
    assert wait_until(lambda: mdp_reg(m, 1, 4) == 3)
    # FC23's read part clears new-data like any read of the read area
    r = m.readwrite_registers(read_address=198, read_count=5, write_address=10, values=[1], device_id=1)
    assert r.registers == [0x13, 3, 7, 8, 9]  # bits 1 and 4 from its own write part
    assert mdp_reg(m, 1, 2) & 1 == 0
    t.close()
    m.close()


def test_fc4_read_of_read_area_clears_new_data(emu):
    t = client(emu.trm_port(1))
    m = client(emu.mdp_port)
    assert exc(t.write_registers(2001, [4])) == 0
    assert wait_until(lambda: mdp_reg(m, 1, 2) & 1 == 1)
    r = m.read_input_registers(198, count=3, device_id=1)
    assert r.registers == [1, 1, 4]
    assert m.read_input_registers(2, count=1, device_id=1).registers == [0]
    t.close()
    m.close()


# ---- static transfer ----

def test_static_mode(tmp_path):
    e = Emulator("--mode", "static", "--static-registers", 10, *FAST)
    try:
        t = client(e.trm_port(1))
        m = client(e.mdp_port)
        assert t.read_holding_registers(2000, count=1).registers == [10]
        assert mdp_reg(m, 1, 9) == 10
        assert exc(t.write_register(2005, 0)) == 0              # same content: no change
        assert t.read_holding_registers(2198, count=1).registers == [0]
        assert exc(t.write_register(2005, 55)) == 0             # single writes anywhere are fine
        assert exc(t.write_registers(2008, [1, 2])) == 0
        # the two writes may go on air in one poll or in two (a busy machine): wait for both
        assert wait_until(lambda: m.read_holding_registers(200, count=10, device_id=1).registers
                          == [0, 0, 0, 0, 55, 0, 0, 1, 2, 0])
        assert m.read_holding_registers(199, count=1, device_id=1).registers == [10]
        assert wait_until(lambda: t.read_holding_registers(2198, count=1).registers == [0])
        assert t.read_holding_registers(2000, count=1).registers == [10]  # static: count stays N
        # beyond N registers: stored, but not a change that goes on air
        assert exc(t.write_register(2100, 9)) == 0
        assert t.read_holding_registers(2198, count=1).registers == [0]
        assert t.read_holding_registers(2100, count=1).registers == [9]
        # and the other direction
        # FC23: the read part shows the state right after the write, before any poll
        r = m.readwrite_registers(read_address=2, read_count=1, write_address=12, values=[3, 4], device_id=1)
        assert r.registers == [0x12]
        assert wait_until(lambda: t.read_holding_registers(2198, count=1).registers[0] & 1 == 1)
        assert t.read_holding_registers(2199, count=5).registers == [10, 0, 0, 3, 4]
        t.close()
        m.close()
    finally:
        assert e.stop() == 0
