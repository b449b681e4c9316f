"""The same spec through a second independent client: mbpoll (Debian, libmodbus inside)."""
import re
import shutil
import subprocess

import pytest

from miptest.emu import FAST, Emulator, wait_until

MBPOLL = shutil.which("mbpoll")
pytestmark = pytest.mark.skipif(MBPOLL is None, reason="mbpoll is not installed (Debian package mbpoll)")


@pytest.fixture
def emu():
    e = Emulator("--stations", 2, *FAST)
    yield e
    assert e.stop() == 0


def mbpoll(port, addr, count=1, unit=1, table=4, values=()):
    """Runs mbpoll once; returns (exit code, {addr: value}, stderr). PDU addressing (-0)."""
    cmd = [MBPOLL, "-m", "tcp", "-p", str(port), "-a", str(unit), "-0", "-1", "-o", "5",
           "-r", str(addr), "-t", str(table)]
    if not values:
        cmd += ["-c", str(count)]  # mbpoll takes the count of a write from the values
    cmd += ["127.0.0.1", *map(str, values)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=30)
    vals = {int(a): int(v) for a, v in re.findall(r"^\[(\d+)\]:\s+(-?\d+)", r.stdout, re.M)}
    return r.returncode, vals, r.stderr


def read(port, addr, count=1, unit=1, table=4):
    rc, vals, err = mbpoll(port, addr, count, unit, table)
    assert rc == 0, err
    return [vals[a] & 0xFFFF for a in range(addr, addr + count)]


@pytest.mark.parametrize("table", [4, 3])  # 4: FC3 holding, 3: FC4 input registers (same map)
def test_map_edges(emu, table):
    trm = emu.trm_port(1)
    assert read(trm, 2000, 125, table=table) == [0] * 125
    assert read(trm, 2223, 125, table=table) == [0] * 125
    assert read(emu.mdp_port, 198, 125, table=table)[:2] == [0, 0]
    for port, addr, count in ((trm, 2149, 1), (trm, 2197, 2), (trm, 2348, 1), (trm, 1999, 1),
                              (emu.mdp_port, 3, 1), (emu.mdp_port, 158, 1), (emu.mdp_port, 341, 8)):
        rc, _, err = mbpoll(port, addr, count, table=table)
        assert rc != 0 and "Illegal data address" in err, (port, addr, err)


def test_read_only_and_dynamic_rules(emu):
    trm = emu.trm_port(1)
    for addr in (2000, 2198, 2200):
        rc, _, err = mbpoll(trm, addr, values=[1, 2])       # FC16 onto read-only
        assert rc != 0 and "Illegal data address" in err
    rc, _, err = mbpoll(trm, 2001, values=[1])               # FC6: no block write in dynamic mode
    assert rc != 0 and "Illegal data address" in err
    rc, _, err = mbpoll(trm, 2002, values=[1, 2])            # not at the first write register
    assert rc != 0 and "Illegal data address" in err
    assert read(trm, 2000) == [0]


def test_unknown_station_0B(emu):
    for unit in (0, 3, 200):
        rc, _, err = mbpoll(emu.mdp_port, 2, unit=unit)
        assert rc != 0 and "Target device failed to respond" in err, unit


def test_block_crosses_and_new_data_clears(emu):
    rc, _, err = mbpoll(emu.trm_port(2), 2001, values=[1, 500, 501, 502])
    assert rc == 0, err
    assert wait_until(lambda: read(emu.mdp_port, 2, unit=2) == [1])
    assert read(emu.mdp_port, 1, unit=1)[0] & 1 == 1            # station 1 answers its polls too
    assert read(emu.mdp_port, 4, unit=2) == [4]
    assert read(emu.mdp_port, 198, 2, unit=2) == [1, 4]          # status alone clears nothing
    assert read(emu.mdp_port, 198, 6, unit=2) == [1, 4, 1, 500, 501, 502]
    assert read(emu.mdp_port, 198, 2, unit=2) == [0, 4]
    assert read(emu.mdp_port, 198, 2, unit=1) == [0, 0]
    assert wait_until(lambda: read(emu.trm_port(2), 2198) == [0])
    assert read(emu.trm_port(2), 2000) == [0]


def test_central_to_station(emu):
    rc, _, err = mbpoll(emu.mdp_port, 10, unit=1, values=[7, 8])
    assert rc == 0, err
    assert read(emu.mdp_port, 9, unit=1) in ([2], [0])           # 0 once already confirmed
    assert wait_until(lambda: read(emu.trm_port(1), 2198) == [1])
    assert read(emu.trm_port(1), 2198, 4, table=3) == [1, 2, 7, 8]
    assert read(emu.trm_port(1), 2198) == [0]
    assert read(emu.trm_port(2), 2198, 2) == [0, 0]


def test_static_mode_single_writes():
    e = Emulator("--mode", "static", "--static-registers", 4, *FAST)
    try:
        assert read(e.trm_port(1), 2000) == [4]
        rc, _, err = mbpoll(e.trm_port(1), 2003, values=[99])    # FC6 is fine in static mode
        assert rc == 0, err
        assert wait_until(lambda: read(e.mdp_port, 2)[0] & 1 == 1)
        assert read(e.mdp_port, 199, 5) == [4, 0, 0, 99, 0]
    finally:
        assert e.stop() == 0
