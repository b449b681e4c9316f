"""Property-based: random loss / duplicate / drop schedules, PLC restarts of either side, both
drives, both read styles, uni- and bidirectional. Whatever happens, every transfer the receiver
completes is exactly one transfer that was sent, register for register, and appears once; every
transfer the sender reports done has arrived exactly once; the rest is reported as failed (or
its sender PLC restarted). Bounded and derandomized, so CI sees the same examples every run."""
import os
import random
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from stlib_sim import Bi, Uni

# STLIB_PROP_SCALE=10 STLIB_PROP_RANDOM=1: a longer, random hunt (not for CI)
SCALE = int(os.environ.get("STLIB_PROP_SCALE", "1"))
SETTINGS = dict(deadline=None, derandomize=not os.environ.get("STLIB_PROP_RANDOM"), database=None,
                suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])
ATTEMPT_LIMIT = 12000     # scans one transfer may take before liveness counts as broken


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_prop")


def radio_fate(seed, p_lost, p_dup, p_drop):
    rnd = random.Random(seed)
    weights = [max(0.0, 1 - p_lost - p_dup - p_drop), p_lost, p_dup, p_drop]
    return lambda src, block: rnd.choices(["ok", "lost", "dup", "drop"], weights)[0]


def attempt_data(rnd, attempt_id, max_len):
    n = rnd.randint(1, max_len)
    return [attempt_id] + [rnd.randrange(65536) for _ in range(n - 1)]


def check_exactly_once(attempts, completed):
    """attempts: [(data, result)], completed: transfers the receiver assembled."""
    keys = [tuple(d) for d, _ in attempts]
    assert len(set(keys)) == len(keys)
    for t in completed:
        assert tuple(t) in keys, f"completed transfer of {len(t)} registers matches nothing sent"
    for data, result in attempts:
        n = sum(1 for t in completed if t == data)
        assert n <= 1, "a transfer arrived twice"
        if result == "done":
            assert n == 1, "sender reported done, receiver has no complete copy"


schedule = st.fixed_dictionaries({
    "seed": st.integers(0, 10**6),
    "polled": st.booleans(),
    "read_mode": st.sampled_from(["trigger", "cyclic"]),
    "read_every": st.integers(1, 4),
    "p_lost": st.sampled_from([0.0, 0.1, 0.25]),
    "p_dup": st.sampled_from([0.0, 0.1, 0.25]),
    "p_drop": st.sampled_from([0.0, 0.1, 0.2] if SCALE == 1 else [0.0, 0.2, 0.4]),
    "chunk": st.sampled_from([3, 16, 64, 123]),
    "transfers": st.integers(1, 3 if SCALE == 1 else 5),
    "write_errors": st.sampled_from([0.0, 0.0, 0.15]),
    "restarts": st.lists(st.tuples(st.integers(10, 1500), st.sampled_from("OC")),
                         max_size=2 if SCALE == 1 else 5),
})


class Runner:
    """Runs attempts on one direction pair, applying PLC restarts at their scan numbers."""

    def __init__(self, bench, restarts):
        self.bench = bench
        self.restarts = sorted(restarts)

    def step_with_restarts(self, on_restart):
        while self.restarts and self.bench.scans >= self.restarts[0][0]:
            _, side = self.restarts.pop(0)
            on_restart(side)
        self.bench.step()


# found by a random hunt: the outstation PLC restarts right after writing record 1; the new
# sender must not take the old record's acknowledgement for its own (fixed by the quiet wait,
# now by the echo check, PROTOCOL.md P8)
@example(s={"seed": 0, "polled": False, "read_mode": "trigger", "read_every": 3, "p_lost": 0.0,
            "p_dup": 0.0, "p_drop": 0.0, "chunk": 3, "transfers": 2, "write_errors": 0.0,
            "restarts": [(10, "O")]})
# found by a wider hunt: heavy loss, drops and restarts of both sides; a receiver that had
# nothing open did not answer the reset record (fixed: every reset is answered once; sessions
# now open with record 1, the case stays as a restart schedule)
@example(s={"seed": 354485, "polled": False, "read_mode": "trigger", "read_every": 2,
            "p_lost": 0.25, "p_dup": 0.25, "p_drop": 0.2, "chunk": 3, "transfers": 5,
            "write_errors": 0.0, "restarts": [(77, "C"), (126, "C"), (157, "O"), (732, "O")]})
# found by a random hunt after sessions opened with record 1: the central restarts mid-transfer
# and the sender's last record (16#FFFF) arrives later: taken for a note sender's one-record
# transfer, a fragment was delivered as complete (fixed: PROTOCOL.md P19 exceptions)
@example(s={"seed": 601960, "polled": True, "read_mode": "trigger", "read_every": 2,
            "p_lost": 0.1, "p_dup": 0.0, "p_drop": 0.2, "chunk": 123, "transfers": 4,
            "write_errors": 0.15, "restarts": [(1007, "O"), (984, "O"), (305, "C")]})
@settings(max_examples=30 * SCALE, **SETTINGS)
@given(s=schedule)
def test_unidirectional_exactly_once(wd, s):
    rnd = random.Random(s["seed"])
    u = Uni(wd, [], polled=s["polled"], read_mode=s["read_mode"], read_every=s["read_every"],
            fate=radio_fate(s["seed"], s["p_lost"], s["p_dup"], s["p_drop"]),
            chunk=s["chunk"], timeout_ms=200)
    for k, port in enumerate((u.port_o, u.port_c)):
        port.fail_rate, port.rng = s["write_errors"], random.Random(s["seed"] + k)
    run = Runner(u.bench, s["restarts"])
    attempts = []
    state = {"abandoned": False}

    def on_restart(side):
        if side == "O":
            u.restart_outstation()
            state["abandoned"] = True
        else:
            u.restart_central()

    u.bench.step(3)
    for k in range(s["transfers"]):
        data = attempt_data(rnd, k + 1, 6 * (s["chunk"] - 1))
        u.src.data = data
        state["abandoned"] = False
        u.snd["xExecute"] = False
        u.bench.step()
        u.snd["xExecute"] = True
        start = u.bench.scans
        while not (u.snd["xDone"] or u.snd["xError"] or state["abandoned"]):
            assert u.bench.scans - start < ATTEMPT_LIMIT, \
                f"attempt {k + 1} stuck in state {u.snd['eState']}"
            run.step_with_restarts(on_restart)
        result = "abandoned" if state["abandoned"] else ("done" if u.snd["xDone"] else "error")
        attempts.append((data, result))
        u.snd["xExecute"] = False
        u.bench.step(2)
    u.bench.step(200)                      # let late duplicates arrive
    for _, r in attempts:
        event(f"sender result: {r}")
    event(f"receiver failed transfers: {min(u.rcv['udiFailedTransfers'], 2)}")
    check_exactly_once(attempts, u.sink.transfers)
    if not s["restarts"]:
        # without restarts and with unlimited retries every transfer completes
        assert all(r == "done" for _, r in attempts)


# found by a random hunt: cyclic reads, the outstation restarts twice; its receiving side took
# the empty input image for its first read, then the central's already delivered 16#FFFF for
# a one-record transfer (fixed: the first read is the first one with a block in it)
@example(s={"seed": 1521, "polled": False, "read_mode": "cyclic", "read_every": 2,
            "p_lost": 0.0, "p_dup": 0.0, "p_drop": 0.0, "chunk": 3, "transfers": 4,
            "write_errors": 0.0, "restarts": [(10, "O"), (26, "O")]})
@settings(max_examples=12 * SCALE, **SETTINGS)
@given(s=schedule)
def test_bidirectional_exactly_once(wd, s):
    rnd = random.Random(s["seed"])
    chunk = max(s["chunk"], 4)
    # "drop" is a block the link reports confirmed (bit 4 clears) but that never reached the
    # peer. The device confirms only what the peer's modem received (note 3: "übertragen und
    # von dort quittiert"), and the bidirectional layout's stale-acknowledgement protection
    # after a restart rests on that (PROTOCOL.md P9); with restarts it becomes "lost" (the link
    # repeats it). Without restarts "drop" stays: it then tests that nothing else depends on it.
    p_lost, p_drop = s["p_lost"], s["p_drop"]
    if s["restarts"]:
        p_lost, p_drop = p_lost + p_drop, 0.0
    bi = Bi(wd, [], [], polled=s["polled"], read_mode=s["read_mode"], read_every=s["read_every"],
            fate=radio_fate(s["seed"], p_lost, s["p_dup"], p_drop), chunk=chunk,
            timeout_ms=200)
    for k, port in enumerate((bi.port_o, bi.port_c)):
        port.fail_rate, port.rng = s["write_errors"], random.Random(s["seed"] + k)
    run = Runner(bi.bench, s["restarts"])
    sides = {"O": (bi.lo, bi.src_o, bi.sink_c), "C": (bi.lc, bi.src_c, bi.sink_o)}
    attempts = {"O": [], "C": []}
    current = {}
    pending = {"O": s["transfers"], "C": s["transfers"]}
    next_id = [1]

    def start(side):
        fb, src, _ = sides[side]
        data = attempt_data(rnd, next_id[0], 5 * (chunk - 2))
        next_id[0] += 1
        src.data = data
        current[side] = data
        pending[side] -= 1
        fb["xExecute"] = False

    def finish(side, result):
        attempts[side].append((current.pop(side), result))

    def on_restart(side):
        plc_attr = "plc_o" if side == "O" else "plc_c"
        fb = bi.lo if side == "O" else bi.lc
        new = bi.bench.restart(getattr(bi, plc_attr), [fb], __import__("stlib_sim").ALL, wd)
        setattr(bi, plc_attr, new)
        fb["xCentral"] = side == "C"
        fb["xPolled"] = s["polled"]
        fb["tTimeout"] = 200 * 1_000_000
        fb["uChunkSize"] = chunk
        fb["xEnable"] = True
        (bi.sink_o if side == "O" else bi.sink_c).current = []
        if side in current:
            finish(side, "abandoned")

    bi.bench.step(3)
    idle = {"O": 0, "C": 0}
    total = 0
    while pending["O"] or pending["C"] or current:
        for side in "OC":
            fb = sides[side][0]
            if side not in current and pending[side]:
                start(side)
                idle[side] = 0
            elif side in current:
                if not fb["xExecute"] and idle[side] >= 1:
                    fb["xExecute"] = True
                idle[side] += 1
                if fb["xSendDone"] or fb["xSendError"]:
                    finish(side, "done" if fb["xSendDone"] else "error")
                    fb["xExecute"] = False
        run.step_with_restarts(on_restart)
        total += 1
        assert total < 3 * ATTEMPT_LIMIT, f"stuck: {bi.lo['eSendState']} {bi.lc['eSendState']}"
    bi.bench.step(200)
    for side in "OC":
        for _, r in attempts[side]:
            event(f"sender result: {r}")
    check_exactly_once(attempts["O"], bi.sink_c.transfers)
    check_exactly_once(attempts["C"], bi.sink_o.transfers)
    if not s["restarts"]:
        assert all(r == "done" for side in "OC" for _, r in attempts[side])
