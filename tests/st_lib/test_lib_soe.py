"""MIP_SoeReader against a relay (issue 35, docs/chain.md "The reader (MIP_SoeReader)"): every
entry reaches the logger once, in order, with the relay's values and time stamps; a read is
acknowledged only after its entries are stored; failures repeat the read and never acknowledge
or deliver twice. The relay is the independent Python one (peers/mippeer/siprotec.py) and,
where the C relay is in the co-simulation, the emulator's core (parametrised `relay`)."""
import pytest

from soe_bench import ERR, STATE, WAIT, Bench, PyRelay, expected, pyrelay, script

ORIGIN = 1767225600000


def make_relay(kind, events=(), **cfg):
    if kind == "py":
        return PyRelay(events, origin_ms=ORIGIN, **cfg)
    from mipcosim.relay import Relay
    return Relay(events, origin_ms=ORIGIN, **cfg)


RELAYS = ["py", "c"]


@pytest.fixture(scope="module")
def wd(tmp_path_factory):
    return tmp_path_factory.mktemp("stlib_soe")


def acks_after_stores(log):
    """Each acknowledgement (seq + 256 n) comes after the store of all n entries of its seq,
    and no entry of that seq is stored after it."""
    for i, ev in enumerate(log):
        if ev[0] != "write" or ev[2] is not None:
            continue
        seq, n = ev[1] & 0xFF, ev[1] >> 8 & 0x3F
        if ev[1] & 0x8000 and seq == 0:
            continue
        stored = [e for e in log[:i] if e[0] == "store" and e[1] == seq]
        assert len(stored) >= n, f"ack {ev[1]:#x} before its {n} entries were stored: {log[:i+1]}"


@pytest.mark.parametrize("relay", RELAYS)
def test_every_entry_once_in_order(wd, relay):
    events = script(14)
    b = Bench(wd, make_relay(relay, events))
    assert b.run_until(lambda: len(b.logger.stored) == 14 and b.fb["xCaughtUp"], 800)
    assert b.logger.stored == expected(events, ORIGIN)
    assert b.relay.entries() == 0
    assert b.fb["udiEntries"] == 14 and b.fb["xError"] is False
    acks_after_stores(b.log)
    b.step(50)   # nothing new: nothing more is stored or written
    assert len(b.logger.stored) == 14 and b.fb["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_READ"]


@pytest.mark.parametrize("relay", RELAYS)
def test_stored_pulse_hands_over_one_entry_a_scan(wd, relay):
    """xStoredPulse with a logger that sets xEntryStored anew every call: the three entries of
    a read are stored in three scans in a row, the first in the scan that takes the read (the
    default handshake takes two scans an entry); every entry once, in order, acknowledged after
    its store."""
    events = script(30, start_s=0.0, every_s=0.001)
    for pulse, gap in ((True, 1), (False, 2)):
        b = Bench(wd, make_relay(relay, events), pulse=pulse)
        at = []                                   # the scan of each store
        while len(b.logger.stored) < 30 and b.scans < 800:
            n = len(b.logger.stored)
            b.step()
            at += [b.scans] * (len(b.logger.stored) - n)
        assert b.run_until(lambda: b.fb["xCaughtUp"], 100)
        assert b.logger.stored == expected(events, ORIGIN) and b.fb["udiEntries"] == 30
        acks_after_stores(b.log)
        assert [at[i + 1] - at[i] for i in range(0, 30, 3)] == [gap] * 10, (pulse, at)
        assert [at[i + 2] - at[i + 1] for i in range(0, 30, 3)] == [gap] * 10, (pulse, at)
        if pulse:
            fast = at[-1] - at[0]
        else:
            assert at[-1] - at[0] >= fast + 2 * 9   # two scans a read more


@pytest.mark.parametrize("relay", RELAYS)
def test_ack_waits_for_a_slow_logger(wd, relay):
    events = script(6, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), delay=7)
    assert b.run_until(lambda: len(b.logger.stored) == 6 and b.fb["xCaughtUp"], 800)
    assert b.logger.stored == expected(events, ORIGIN)
    acks_after_stores(b.log)
    assert b.acks()[0] == 1 + 3 * 256        # the first read: seq 1, three entries
    assert b.fb["udiAcks"] == 2


def test_read_failures_are_read_again_never_acknowledged(wd):
    events = script(9, start_s=0.0, every_s=0.002)
    b = Bench(wd, make_relay("py", events))
    b.client.lose_read_answer = 5
    b.run_until(lambda: b.client.reads >= 4, 100)
    assert b.client.writes == [] and b.logger.stored == []
    assert b.fb["xLinkError"] and b.fb["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_LINK"]
    assert b.run_until(lambda: len(b.logger.stored) == 9 and b.fb["xCaughtUp"], 800)
    assert b.logger.stored == expected(events, ORIGIN)
    assert not b.fb["xLinkError"] and b.fb["wLinkError"] == 0x0B


@pytest.mark.parametrize("relay", RELAYS)
@pytest.mark.parametrize("mode", ["trigger", "cyclic"])
def test_lost_ack_answer_delivers_nothing_twice(wd, relay, mode):
    """The relay took the acknowledgement, its answer was lost: the next read shows the raised
    number (or no blocks); with cyclic reads an older image may make the block write the old
    acknowledgement again, which the relay refuses with exception 03. No entry twice."""
    events = script(10, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), read_mode=mode, read_every=3, tAckRetry=20_000_000)
    b.client.lose_write_answer = 3
    assert b.run_until(lambda: len(b.logger.stored) == 10 and b.fb["xCaughtUp"], 1500)
    assert b.logger.stored == expected(events, ORIGIN)
    assert b.fb["udiWriteErrors"] >= 3 and not b.fb["xError"]
    assert b.relay.entries() == 0
    acks_after_stores(b.log)


def test_lost_ack_request_is_written_again(wd):
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay("py", events))
    b.client.lose_write_request = 2
    assert b.run_until(lambda: b.fb["xCaughtUp"] and len(b.logger.stored) == 3, 800)
    assert [v for v, _ in b.client.writes] == [1 + 3 * 256] * 3
    assert b.logger.stored == expected(events, ORIGIN)


@pytest.mark.parametrize("relay", RELAYS)
def test_logger_full_stops_reading_and_the_relay_keeps_the_rest(wd, relay):
    events = script(8, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), capacity=2, follow_req=True)
    b.step(200)
    assert len(b.logger.stored) == 2
    # the two stored were acknowledged (seq 1, 2 entries); the relay keeps the other six
    assert b.acks() == [1 + 2 * 256]
    assert b.relay.entries() == 6
    assert b.fb["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_LOGGER_FULL"]
    assert not b.fb["xReadReq"] and not b.fb["xEntryValid"]
    reads = b.client.reads
    b.step(100)
    assert b.client.reads == reads and b.relay.entries() == 6 and not b.fb["xError"]
    b.logger.capacity = None
    assert b.run_until(lambda: len(b.logger.stored) == 8 and b.fb["xCaughtUp"], 800)
    assert b.logger.stored == expected(events, ORIGIN)


@pytest.mark.parametrize("relay", RELAYS)
def test_reset_list_only_on_request(wd, relay):
    events = script(7, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), capacity=0)     # a logger that stores nothing
    b.step(100)
    assert b.relay.entries() == 7 and b.client.writes == []  # never reset by itself
    b.fb["xResetList"] = True
    b.step(20)
    assert b.relay.entries() == 0 and b.fb["udiResets"] == 1
    assert b.client.writes == [(0x8000, None)]
    b.fb["xResetList"] = False
    b.logger.capacity = None
    b.relay.add(b.now_ns / 1e9 + 0.05, [0x0101, 7, 0x0101, 1])
    assert b.run_until(lambda: len(b.logger.stored) == 1 and b.fb["xCaughtUp"], 300)
    assert b.logger.stored[0].address == 7 and not b.fb["xError"]


@pytest.mark.parametrize("relay", RELAYS)
def test_overflow_keeps_order(wd, relay):
    """A burst larger than the relay's capacity before the first read: the relay drops the
    oldest not offered (its choice); the reader delivers what the relay kept, in order."""
    events = script(12, start_s=0.0, every_s=0.0)
    b = Bench(wd, make_relay(relay, events, capacity=5))
    assert b.run_until(lambda: b.fb["xCaughtUp"] and b.scans > 20, 800)
    exp = expected(events, ORIGIN)
    assert b.logger.stored == exp[:3] + exp[-2:]    # offered first three stay, newest two
    assert not b.fb["xError"]


# ---------------------------------------------------------------- a relay that misbehaves

@pytest.mark.parametrize("name,tamper,error", [
    ("four blocks", lambda r: [r[0], (r[1] & 0xFF) | 4 << 8] + r[2:], "MIP_SOE_ERR_BAD_ANSWER"),
    ("count below blocks", lambda r: [0] + r[1:] if r[1] >> 8 else r, "MIP_SOE_ERR_BAD_ANSWER"),
    ("seq 0 with blocks", lambda r: [r[0], r[1] & 0xFF00] + r[2:], "MIP_SOE_ERR_BAD_ANSWER"),
])
def test_garbage_is_a_named_error_and_nothing_is_delivered(wd, name, tamper, error):
    b = Bench(wd, make_relay("py", script(3, start_s=0.0, every_s=0.001)), tRetryTimeout=300_000_000)
    b.client.tamper = tamper
    assert b.run_until(lambda: b.fb["xError"], 200), name
    assert b.fb["eErrorId"] == ERR[error] and b.fb["eState"] == STATE["MIP_SOE_ERROR"]
    assert b.logger.stored == [] and b.client.writes == []
    assert b.fb["udiBadReads"] >= 2 and b.relay.entries() == 3
    b.client.tamper = None
    b.fb["xEnable"] = False
    b.step()
    b.fb["xEnable"] = True               # the operator's reset: a good relay reads fine
    assert b.run_until(lambda: len(b.logger.stored) == 3 and b.fb["xCaughtUp"], 300)


def test_garbage_once_is_read_again(wd):
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay("py", events))
    bad = [2]

    def tamper(r):
        if bad[0] and r[1] >> 8:
            bad[0] -= 1
            return [r[0], r[1] | 0x3F00] + r[2:]
        return r
    b.client.tamper = tamper
    assert b.run_until(lambda: len(b.logger.stored) == 3 and b.fb["xCaughtUp"], 300)
    assert b.logger.stored == expected(events, ORIGIN) and b.fb["udiBadReads"] == 2


def test_sequence_backwards_is_a_named_error(wd):
    """After the third acknowledgement the relay shows a number before it (a garbled register,
    or a relay that lost its state other than by a restart, whose first number is 1):
    MIP_SOE_ERR_SEQUENCE, nothing delivered."""
    b = Bench(wd, make_relay("py", script(12, start_s=0.0, every_s=0.001)), tRetryTimeout=200_000_000)
    b.client.tamper = lambda r: [r[0], r[1] - 2] + r[2:] if (r[1] & 0xFF) == 4 else r
    assert b.run_until(lambda: b.fb["xError"], 300)
    assert b.fb["eErrorId"] == ERR["MIP_SOE_ERR_SEQUENCE"] and b.fb["udiRelayRestarts"] == 0
    assert len(b.logger.stored) == 9 and b.fb["udiAcks"] == 3 and b.relay.entries() == 3


def test_a_number_1_that_is_no_restart_ends_in_a_named_error(wd):
    """The price of the restart rule: a relay that shows number 1 for good where 3 is due (a
    garbled register, two reads the same) is taken for a restarted relay; its entries (the
    relay's own, each once) are handed over, and the relay refuses their acknowledgement:
    MIP_SOE_ERR_ACK_REFUSED after tAckTimeout, nothing wrong delivered, nothing twice."""
    events = script(8, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay("py", events), tAckTimeout=400_000_000, tAckRetry=50_000_000)
    b.client.tamper = lambda r: [r[0], r[1] - 2] + r[2:] if (r[1] & 0xFF) == 3 else r
    assert b.run_until(lambda: b.fb["xError"], 300)
    assert b.fb["eErrorId"] == ERR["MIP_SOE_ERR_ACK_REFUSED"] and b.fb["udiRelayRestarts"] == 1
    assert b.logger.stored == expected(events, ORIGIN) and b.relay.entries() == 2


def restart_relay(b, kind, events):
    """A power cycle of the relay: recorder empty, number 0, `events` to come."""
    if kind == "py":
        b.relay = b.client.relay = make_relay("py", events)
        b.relay.advance(b.now_ns)
    else:
        b.relay.restart(events)


@pytest.mark.parametrize("relay", RELAYS)
@pytest.mark.parametrize("at", [4, 6])
def test_a_relay_restart_with_entries_right_after_it(wd, relay, at):
    """The relay restarts while the reader holds its second read (4: one of its entries
    stored; 6: all stored, the acknowledgement due) and records new entries before any read
    sees its 0: the reader takes its number 1 (twice the same) as a restarted relay, counts it,
    and goes on; no error, every entry the reader took once, in order, then every new one."""
    events = script(9, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), tAckRetry=50_000_000)
    assert b.run_until(lambda: len(b.logger.stored) == at, 300)
    now_s = b.now_ns / 1e9
    later = script(10, start_s=now_s + 0.001, every_s=0.002, seed=5)
    restart_relay(b, relay, later)
    assert b.run_until(lambda: b.fb["xCaughtUp"] and len(b.logger.stored) >= 6 + 10, 800), b.log[-5:]
    k = len(b.logger.stored) - 10
    assert k == 6        # the open read (seq 2) is handed over whole; seq 3 went with the relay
    assert b.logger.stored == expected(events, ORIGIN)[:k] + expected(later, ORIGIN)
    assert b.fb["udiRelayRestarts"] == 1 and not b.fb["xError"]
    assert b.fb["eLastErrorId"] == ERR["MIP_CHAIN_ERR_NONE"] and b.relay.entries() == 0


@pytest.mark.parametrize("relay", RELAYS)
def test_a_relay_restart_seen_as_0_is_counted(wd, relay):
    """The reader reads the restarted relay's 0 before its next entry: the open read is
    dropped, the restart counted once, the new entries follow."""
    events = script(6, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events))
    assert b.run_until(lambda: b.fb["xCaughtUp"] and len(b.logger.stored) == 6, 300)
    later = script(4, start_s=b.now_ns / 1e9 + 0.3, seed=3)
    restart_relay(b, relay, later)
    assert b.run_until(lambda: b.fb["xCaughtUp"] and len(b.logger.stored) == 10, 300)
    assert b.logger.stored == expected(events, ORIGIN) + expected(later, ORIGIN)
    assert b.fb["udiRelayRestarts"] == 1 and not b.fb["xError"]


def test_a_relay_that_ignores_the_ack(wd):
    """The acknowledgement is answered but nothing is deleted: the acknowledged number stays;
    after tAckTimeout MIP_SOE_ERR_SEQ_UNCHANGED, and the entries were delivered once."""
    relay = make_relay("py", script(3, start_s=0.0, every_s=0.001))
    relay.rec._control = lambda v: None
    b = Bench(wd, relay, tAckTimeout=300_000_000)
    assert b.run_until(lambda: b.fb["xError"], 300)
    assert b.fb["eErrorId"] == ERR["MIP_SOE_ERR_SEQ_UNCHANGED"]
    assert len(b.logger.stored) == 3 and len(b.acks()) == 1


def test_a_relay_that_refuses_every_ack(wd):
    relay = make_relay("py", script(3, start_s=0.0, every_s=0.001))

    def refuse(v):
        raise pyrelay.ModbusError(3)
    relay.rec._control = refuse
    b = Bench(wd, relay, tAckTimeout=400_000_000, tAckRetry=50_000_000)
    assert b.run_until(lambda: b.fb["xError"], 300)
    assert b.fb["eErrorId"] == ERR["MIP_SOE_ERR_ACK_REFUSED"]
    assert len(b.logger.stored) == 3                 # once, not once per retry
    assert len(b.client.writes) >= 3 and all(exc == 3 for _, exc in b.client.writes)


def test_no_read_for_tReadTimeout(wd):
    b = Bench(wd, make_relay("py"), tReadTimeout=200_000_000)
    b.client.lose_read_answer = 10 ** 6
    b.step(30)
    assert b.fb["xError"] and b.fb["eErrorId"] == ERR["MIP_SOE_ERR_NO_READ"]
    b.client.lose_read_answer = 0
    b.step(4)
    assert not b.fb["xError"] and b.fb["eLastErrorId"] == ERR["MIP_SOE_ERR_NO_READ"]


def test_bad_seq_bits_parameter(wd):
    b = Bench(wd, make_relay("py"), uSeqBits=9)
    b.step(2)
    assert b.fb["xError"] and b.fb["eErrorId"] == ERR["MIP_SOE_ERR_PARAM"]


def test_small_sequence_numbers_wrap(wd):
    """seq-bits 2: numbers 1, 2, 3, 1, ... (docs/chain.md); the reader follows the wrap."""
    events = script(20, every_s=0.03)
    b = Bench(wd, make_relay("py", events, seq_bits=2), uSeqBits=2)
    assert b.run_until(lambda: len(b.logger.stored) == 20 and b.fb["xCaughtUp"], 1500)
    assert b.logger.stored == expected(events, ORIGIN) and not b.fb["xError"]
    assert set(b.logger.seqs) == {1, 2, 3}


@pytest.mark.parametrize("relay", RELAYS)
@pytest.mark.parametrize("at", [2, 3])
def test_a_relay_restart_while_a_read_numbered_1_is_open_loses_nothing(wd, relay, at):
    """The window [S5] 5.2.5 leaves open (model/soe.pml, soe-relayack1): the reader holds its
    first read (number 1; 2: two of its three entries stored, 3: all stored, the
    acknowledgement due in the next scan) when the relay restarts and records new entries at
    once. The acknowledgement 1 + 3 x 256 would be taken by the restarted relay for its own
    first read and delete three entries nobody read. The verify read before acknowledging a
    read numbered 1 sees the new blocks instead: the restart is taken up, nothing is written
    to the restarted relay before its entries are read, and every new entry is stored."""
    events = script(3, start_s=0.0, every_s=0.001)
    b = Bench(wd, make_relay(relay, events), tAckRetry=50_000_000)
    assert b.run_until(lambda: len(b.logger.stored) == at, 300)
    assert b.fb["wEntrySeq"] == 1 and b.client.writes == []
    # the new entries are recorded before the block's next call (time now: already due)
    later = script(6, start_s=b.now_ns / 1e9, every_s=0.0, seed=7)
    restart_relay(b, relay, later)
    b.relay.advance(b.now_ns)
    assert b.relay.entries() == 6
    at_restart = len(b.log)
    assert b.run_until(lambda: b.fb["xCaughtUp"] and len(b.logger.stored) >= 3 + 6, 800), b.log[-8:]
    assert b.logger.stored == expected(events, ORIGIN)[:3] + expected(later, ORIGIN)
    # nothing was written to the restarted relay before its first entry was stored: the old
    # read's acknowledgement 1 + 3 x 256 never reached it
    stores = [i for i, ev in enumerate(b.log) if ev[0] == "store"]
    first_new = stores[3]
    assert [ev for ev in b.log[at_restart:first_new] if ev[0] == "write"] == [], b.log[at_restart:]
    assert b.fb["udiRelayRestarts"] == 1 and not b.fb["xError"] and b.relay.entries() == 0


def test_only_reads_numbered_1_are_read_again_before_their_acknowledgement(wd):
    """The verify read costs one read per 2^uSeqBits - 1 reads: with numbers 1, 2, 3, 1, ...
    (seq-bits 2) the block waits in MIP_SOE_VERIFY before each acknowledgement of a read
    numbered 1, and before no other."""
    events = script(20, every_s=0.03)
    b = Bench(wd, make_relay("py", events, seq_bits=2), uSeqBits=2)
    episodes, prev = [], None
    while not (len(b.logger.stored) == 20 and b.fb["xCaughtUp"]) and b.scans < 1500:
        b.step()
        st = b.fb["eState"]
        if st == STATE["MIP_SOE_VERIFY"] and prev != st:
            episodes.append(b.fb["wEntrySeq"])
            assert b.fb["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_VERIFY"] and b.fb["xReadReq"]
        prev = st
    assert b.logger.stored == expected(events, ORIGIN) and not b.fb["xError"]
    ones = [v for v in b.acks() if v & 0xFF == 1]
    assert episodes == [1] * len(ones) and len(ones) >= 2 and len(b.acks()) > len(ones)


def test_disabled_while_a_read_is_open_says_so_and_the_next_enable_goes_on(wd):
    """xLeftOpen (0.1.0's xAborted): xEnable fell while a read was open; its entries stay in the
    relay and the next enable hands over the rest: nothing lost. The entry shown when xEnable fell
    was stored by this logger but not counted (the block reads xEntryStored in the call after),
    so it comes once more: a known duplicate of a disable, not of this interface change."""
    events = script(6)
    b = Bench(wd, make_relay("py", events))
    assert b.run_until(lambda: b.fb["xEntryValid"], 300)      # a read is open
    assert b.fb["xValid"] and b.fb["xBusy"] and not b.fb["xLeftOpen"]
    b.fb["xEnable"] = False
    b.step()
    assert b.fb["xLeftOpen"] and not b.fb["xValid"] and not b.fb["xBusy"]
    assert b.fb["eWaitReason"] == WAIT["MIP_CHAIN_WAIT_NONE"]
    b.fb["xEnable"] = True
    b.step()
    shown = b.logger.stored[-1]
    assert not b.fb["xLeftOpen"]
    assert b.run_until(lambda: len(b.logger.stored) == 7 and b.fb["xCaughtUp"], 800)
    want = expected(events, ORIGIN)
    assert [e for i, e in enumerate(b.logger.stored) if e not in b.logger.stored[:i]] == want
    assert [e for e in b.logger.stored if b.logger.stored.count(e) > 1] == [shown, shown]
