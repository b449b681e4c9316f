"""MIP_SoeReader over PLC restarts (docs/chain.md "The reader", restarts). Warm: the instance
and the logger are RETAIN, xRetained is set, and the PLC comes back with its last snapshot
(the logger's store as it was then, too): every entry reaches the logger exactly once. Cold:
the block starts from nothing; the relay still holds what was not acknowledged, so nothing is
lost, but entries of the open read stored before the restart come again (duplicates)."""
import random

import pytest

from soe_bench import STATE, WAIT, Bench, expected, script
from test_lib_soe import ORIGIN, make_relay


@pytest.fixture(scope="module")
def wd(tmp_path_factory):
    return tmp_path_factory.mktemp("stlib_soe_restart")


def test_ack_waits_for_the_snapshot(wd):
    b = Bench(wd, make_relay("py", script(3, start_s=0.0, every_s=0.001)), retained=True)
    seen = []
    orig = b.step

    def step_without_snapshots(n=1):
        for _ in range(n):
            keep = b.snapshots
            orig()
            b.snapshots = keep          # a runtime that never completes a snapshot
            seen.append(b.fb["eWaitReason"])
    step_without_snapshots(60)
    assert len(b.logger.stored) == 3 and b.client.writes == []
    assert seen[-1] == WAIT["MIP_CHAIN_WAIT_SNAPSHOT"] and b.fb["xSnapshotReq"]
    orig(10)                             # snapshots complete again: the acknowledgement goes
    assert b.acks() == [1 + 3 * 256]


@pytest.mark.parametrize("relay", ["py", "c"])
@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_warm_restarts_deliver_every_entry_exactly_once(wd, relay, seed):
    """Seeds 4 and 5: the logger of the chain's outstation (xStoredPulse, one entry a scan).
    The runtime's count of snapshots starts again from 0 at each restart, as plcrt's: the block
    sees the restart, and an acknowledgement the snapshot holds as due is decided by a new read
    (a lost answer's refused repeat no longer holds it up), so 72 events keep it busy over at
    least ten restarts."""
    rnd = random.Random(seed)
    events = script(72, start_s=0.0, every_s=0.007, seed=seed)
    b = Bench(wd, make_relay(relay, events), retained=True, delay=rnd.randrange(3),
              pulse=seed > 3)
    b.client.lose_write_answer = 2
    restarts = 0
    for _ in range(60):
        b.step(rnd.randrange(1, 12))
        if b.snapshot and rnd.random() < 0.5:
            b.warm_restart()
            restarts += 1
        if len(b.logger.stored) == 72 and b.fb["xCaughtUp"]:
            break
    assert b.run_until(lambda: len(b.logger.stored) == 72 and b.fb["xCaughtUp"], 1500)
    assert restarts >= 10
    assert b.logger.stored == expected(events, ORIGIN)
    assert b.relay.entries() == 0 and not b.fb["xError"]


def test_warm_restart_in_the_middle_of_a_read(wd):
    """Restart after the first entry of a read of three was stored (and a snapshot holds it):
    the block goes on with the second; the first is not handed over again."""
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay("py", events), retained=True)
    assert b.run_until(lambda: len(b.logger.stored) == 1 and b.snapshot and b.snapshot[1] == 1, 100)
    b.step()
    b.warm_restart()
    at = len(b.log)
    assert b.run_until(lambda: len(b.logger.stored) == 3 and b.fb["xCaughtUp"], 300)
    assert b.logger.stored == expected(events, ORIGIN)
    # after the restart: the second and third (what the snapshot's logger lacks), not the first
    assert [x[2] for x in b.log[at:] if x[0] == "store"] == [1, 2]


def test_cold_restart_loses_nothing_but_may_duplicate(wd):
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay("py", events), delay=3)
    assert b.run_until(lambda: len(b.logger.stored) == 2, 100)
    b.cold_restart()
    assert b.run_until(lambda: b.fb["xCaughtUp"], 300)
    exp = expected(events, ORIGIN)
    # the open read comes again from its first entry: the two stored before are duplicated
    assert b.logger.stored == exp[:2] + exp
    assert b.relay.entries() == 0


@pytest.mark.parametrize("relay", ["py", "c"])
def test_a_read_numbered_1_back_from_a_snapshot_after_a_relay_restart(wd, relay):
    """A power dip at the outstation restarts both: the PLC comes back with a snapshot that
    holds its first read (number 1) stored whole, the acknowledgement not yet written; the relay
    came back empty and recorded new entries in the meantime. The block reads the read
    numbered 1 again before acknowledging it (MIP_SOE_VERIFY), sees the restarted relay's
    blocks and takes them up: its acknowledgement 1 + 3 x 256 never reaches the restarted
    relay, and every new entry is stored, exactly once."""
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), retained=True)
    assert b.run_until(lambda: b.snapshot and b.snapshot[1] == 3, 200)
    b.warm_restart()
    assert b.fb["eState"] == STATE["MIP_SOE_VERIFY"] and b.client.writes == []
    _relay_restarts_and_every_entry_is_stored(b, relay, events, seed=11)


@pytest.mark.parametrize("relay", ["py", "c"])
def test_an_acknowledgement_in_flight_in_the_snapshot_is_not_written_after_the_restart(wd, relay):
    """The runtime's periodic snapshot catches the acknowledgement of the first read (number 1)
    raised but not yet sent; the PLC dies and comes back with it, and the relay restarted and
    recorded new entries meanwhile (one power dip). The block sees its restart (the runtime's
    count of snapshots starts again from 0), ends that write as failed instead of sending it,
    and a new read decides: the restarted relay's entries are stored, none deleted unread."""
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), retained=True, tAckRetry=50_000_000)
    b.client.hold_writes = True
    assert b.run_until(lambda: b.fb["xWriteReq"], 200)
    assert b.fb["wWriteValue"] == 1 + 3 * 256 and b.client.writes == []
    b.take_snapshot()                          # periodic: the write is in it, raised
    b.warm_restart()
    b.client.hold_writes = False
    _relay_restarts_and_every_entry_is_stored(b, relay, events, seed=13)


def _relay_restarts_and_every_entry_is_stored(b, relay, events, seed):
    """The relay restarts with 5 new entries while the block holds its first read (3 entries):
    every entry of both is stored once, in order, and nothing is written to the restarted relay
    before its own first entry was stored (no acknowledgement of the old read reaches it)."""
    from test_lib_soe import restart_relay
    later = script(5, start_s=b.now_ns / 1e9, every_s=0.0, seed=seed)
    restart_relay(b, relay, later)
    b.relay.advance(b.now_ns)
    at = len(b.log)
    assert b.run_until(lambda: b.fb["xCaughtUp"] and len(b.logger.stored) >= 3 + 5, 600), b.log[-8:]
    assert b.logger.stored == expected(events, ORIGIN) + expected(later, ORIGIN)
    first_new = [i for i, ev in enumerate(b.log) if ev[0] == "store"][3]
    assert [ev for ev in b.log[at:first_new] if ev[0] == "write"] == [], b.log[at:]
    assert b.fb["udiRelayRestarts"] == 1 and b.relay.entries() == 0 and not b.fb["xError"]
