"""The note-only peer's protocol core (Piciorgros note, section 2): numbering, the strict and
the lenient receiver, the senders, and exactly-once over a lossy link between two note peers."""
import random

import pytest

from mippeer.peer import Peer
from mippeer.protocol import LAST, Receiver, Sender, TransferTooLong, numbers_for


def test_numbering_follows_the_note():
    assert numbers_for(5) == [1, 2, 3, 4, LAST]
    assert numbers_for(1) == [LAST]          # a one-record transfer: only "the last record"
    with pytest.raises(TransferTooLong):
        numbers_for(65536)
    assert numbers_for(65535)[-2:] == [65534, LAST]


def test_note_example_counter_by_counter():
    """Section 2.1.1: five records, record 2 lost once on the way; the central acknowledges
    0, 1, 1, 2, 3, 4, 65535 and the outstation sends record 2 again."""
    r = Receiver()
    s = Sender([[n] * 3 for n in range(5)])
    ack, acks, sent = 0, [0], []
    lost_once = {2}
    while not s.done:
        s.on_ack(ack)
        if s.done:
            break
        number, payload = s.current()
        sent.append(number)
        if number in lost_once:
            lost_once.discard(number)
        else:
            ack = r.on_record(number, payload)
        acks.append(ack)
    assert sent == [1, 2, 2, 3, 4, LAST]
    assert acks == [0, 1, 1, 2, 3, 4, LAST]
    assert r.transfers == [[[n] * 3 for n in range(5)]]


@pytest.mark.parametrize("lenient", [False, True])
def test_receiver_accepts_only_the_next_number(lenient):
    r = Receiver(lenient=lenient)
    assert r.on_record(2, [2]) == 0 and r.unexpected == 1      # a transfer starts with 1
    assert r.on_record(0, []) == 0                             # 0 is no record
    assert r.on_record(1, [1]) == 1
    assert r.on_record(1, [1]) == 1 and r.duplicates == 1      # repeated: old ack again
    assert r.on_record(3, [3]) == 1                            # a gap: old ack again
    assert r.on_record(2, [2]) == 2
    assert r.on_record(LAST, [9]) == LAST
    assert r.transfers == [[[1], [2], [9]]]
    assert r.on_record(LAST, [9]) == LAST and r.transfers == [[[1], [2], [9]]]
    assert r.on_record(1, [5]) == 1 and r.current == [[5]]     # next transfer after 0xFFFF


def test_strict_receiver_ignores_record_1_inside_a_transfer():
    r = Receiver()
    r.on_record(1, [1])
    r.on_record(2, [2])
    assert r.on_record(1, [9]) == 2
    assert r.current == [[1], [2]] and r.abandoned == []


def test_lenient_receiver_starts_a_new_transfer_with_record_1():
    r = Receiver(lenient=True)
    r.on_record(1, [1])
    r.on_record(2, [2])
    assert r.on_record(1, [9]) == 1
    assert r.abandoned == [[[1], [2]]] and r.current == [[9]]


@pytest.mark.parametrize("lenient", [False, True])
def test_lone_last_record_is_a_one_record_transfer_after_0_only(lenient):
    r = Receiver(lenient=lenient)
    assert r.on_record(LAST, [4]) == LAST and r.transfers == [[[4]]]
    assert r.on_record(LAST, [4]) == LAST and r.duplicates == 1   # after 0xFFFF: a repeat
    assert r.transfers == [[[4]]]


def test_sender_moves_on_only_when_its_number_comes_back():
    s = Sender([[1], [2], [3]])
    assert s.current() == (1, [1])
    assert not s.on_ack(0) and not s.on_ack(LAST) and not s.on_ack(2)
    assert s.on_ack(1) and s.current() == (2, [2])
    assert not s.on_ack(1)                    # record 2 lost: the old number, send 2 again
    assert not s.on_ack(0)                    # strict: 0 is not our number either
    assert s.on_ack(2) and s.current() == (LAST, [3])
    assert s.on_ack(LAST) and s.done


def test_lenient_sender_starts_again_when_the_receiver_shows_0():
    s = Sender([[1], [2], [3]], lenient=True)
    assert not s.on_ack(0)                    # nothing sent yet: stays at record 1
    s.on_ack(1)
    assert s.on_ack(0) and s.current() == (1, [1]) and s.restarts == 1


def test_blocks_of_both_layouts():
    out = Peer("outstation", [[7, 8]], layout="uni")
    assert out.step(0.0, [0, 0]) == [LAST, 7, 8]
    cen = Peer("central", layout="uni")
    assert cen.step(0.0, [1, 3, LAST, 7, 8]) == [LAST] and cen.receiver.transfers == [[[7, 8]]]
    # note 2.2: outstation writes [its counter, its ack], the central [its ack, its counter]
    out = Peer("outstation", [[1], [2]], layout="bi")
    cen = Peer("central", [[5], [6]], layout="bi")
    assert out.step(0.0, [0, 0]) == [1, 0, 1]
    assert cen.step(0.0, [1, 3, 1, 0, 1]) == [1, 1, 5]
    assert out.step(0.1, [1, 3, 1, 1, 5]) == [LAST, 1, 2]
    assert cen.step(0.2, [1, 3, LAST, 1, 2]) == [LAST, LAST, 6]
    assert out.step(0.3, [1, 3, LAST, LAST, 6]) == [0, LAST]
    assert cen.receiver.transfers == [[[1], [2]]] and out.receiver.transfers == [[[5], [6]]]


def test_static_mode_writes_the_fixed_block():
    out = Peer("outstation", [[7, 8], [9]], layout="uni", static_registers=5)
    assert out.step(0.0, [0, 0]) == [1, 7, 8, 0, 0]
    with pytest.raises(ValueError):
        Peer("outstation", [[1] * 5], layout="bi", static_registers=6)


def test_spontaneous_sender_repeats_after_its_timeout_polled_answers_requests():
    out = Peer("outstation", [[1], [2]], drive="spontaneous", retransmit_s=2)
    assert out.step(0, [0, 0]) == [1, 1]
    assert out.step(1, [0, 0]) is None
    assert out.step(2, [0, 0]) == [1, 1]
    pol = Peer("outstation", [[1], [2]], drive="polled")
    assert pol.step(0, [0, 0]) is None and pol.step(5, [0, 0]) is None
    assert pol.step(6, [1, 1, 0]) == [1, 1]      # the central's block is the request
    assert pol.step(7, [1, 1, 1]) == [LAST, 2]


class LossyLink:
    """Two MIP buffers and a poll that moves pending blocks with loss, duplicates and overwrites."""

    def __init__(self, rng, loss):
        self.rng, self.loss = rng, loss
        self.pending = {"outstation": None, "central": None}
        self.inbox = {"outstation": None, "central": None}

    def write(self, side, block):
        self.pending[side] = list(block)  # a newer block replaces an unsent one

    def poll(self):
        for src, dst in (("central", "outstation"), ("outstation", "central")):
            if self.pending[src] is not None and self.rng.random() >= self.loss:
                self.inbox[dst] = self.pending[src]  # overwrites unread data
                if self.rng.random() >= self.loss:  # confirmation arrived: else sent again
                    self.pending[src] = None

    def read(self, side):
        block, self.inbox[side] = self.inbox[side], None
        return [1, len(block)] + block if block is not None else [0, 0]


@pytest.mark.parametrize("lenient", [False, True])
@pytest.mark.parametrize("layout", ["uni", "bi"])
@pytest.mark.parametrize("drive", ["polled", "spontaneous"])
@pytest.mark.parametrize("seed", range(4))
def test_two_note_peers_exactly_once_over_a_lossy_link(layout, drive, lenient, seed):
    rng = random.Random(seed)
    up = [[rng.randrange(65536) for _ in range(rng.randrange(1, 20))] for _ in range(12)]
    down = ([[rng.randrange(65536) for _ in range(5)] for _ in range(1 + seed % 4)]
            if layout == "bi" else None)
    kw = dict(layout=layout, drive=drive, lenient=lenient, retransmit_s=3, request_s=2)
    out = Peer("outstation", up, **kw)
    cen = Peer("central", down, **kw)
    link = LossyLink(rng, 0.3)
    for t in range(5000):
        for side, peer in (("outstation", out), ("central", cen)):
            block = peer.step(t, link.read(side))
            if block is not None:
                link.write(side, block)
        link.poll()
        if out.done and cen.done and cen.receiver.transfers and (
                down is None or out.receiver.transfers):
            break
    assert cen.receiver.transfers == [up]
    assert out.done
    if down is not None:
        assert out.receiver.transfers == [down] and cen.done
