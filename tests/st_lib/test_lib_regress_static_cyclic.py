"""Regression: static mode with cyclic (OpenPLC-style) I/O and a late xWriteDone.

OpenPLC writes the located range every cycle; the program reports the write done only some
periods after it raised xWriteReq. The record can thus reach the receiver, and its
acknowledgement be read, before xWriteDone. MIP_Sender counted an acknowledgement only when
read after the write was done, and static mode never sends the unchanged block again (nor
the receiver its unchanged acknowledgement): the transfer stalled after record 1. Run through
the virtual-time chain of docs/tools/chainsim.py (the program built from st_lib in the
soft-PLC runtime, whose master has the cyclic policy, and the emulator core, in the
co-simulation kernel)."""
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

if not (REPO / "build" / "cosim" / "libmipcosim.so").is_file():
    pytest.fail("build/cosim/libmipcosim.so not built: run make first (these tests cannot run without it)", pytrace=False)

from mipdocs.chainsim import Chain, Side  # noqa: E402

FFFF = 0xFFFF
N = 40


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("regress_static_cyclic")


@pytest.mark.parametrize("done_periods", [1.5, 3, 4])
def test_static_cyclic_late_write_done(workdir, done_periods):
    data = [(7 * i + 3) % 65536 for i in range(2 * (N - 1) + 10)]
    o = Side("outstation", "sender", data=data, chunk=N, static=True, cyclic_ms=500,
             timeout_ms=1500, cyclic_done_periods=done_periods)
    c = Side("central", "receiver", chunk=N, static=True, cyclic_ms=500, timeout_ms=1500,
             read_phase_ms=250)
    ch = Chain(workdir, o, c, mode=1, static_registers=N, seed=1)
    try:
        ok = ch.run_until(lambda: o.send_done, 60_000)
        state = (o.fbv("eState"), o.fbv("wRecord"), o.fbv("wLastAck"))
    finally:
        ch.close()
    assert ok, f"sender did not finish (state, record, last ack = {state}), received {c.received}"
    assert [k for k, _ in c.received] == [1, 2, FFFF]
    got = [w for _, payload in c.received for w in payload]
    assert got[:len(data)] == data and not any(got[len(data):])
    assert not o.errors and not c.errors
