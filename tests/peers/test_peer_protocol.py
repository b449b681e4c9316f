"""The Python peer's protocol core: numbering, receiver decisions, and exactly-once over a lossy link."""
import random

import pytest

from mippeer.peer import Peer
from mippeer.protocol import LAST, Receiver, Sender, TransferTooLong, numbers_for


def test_numbering_follows_the_note():
    assert numbers_for(5) == [1, 2, 3, 4, LAST]
    with pytest.raises(TransferTooLong):
        numbers_for(65536)
    assert numbers_for(65535)[-2:] == [65534, LAST]


def test_one_record_transfer_is_closed_by_an_empty_last_record():
    s = Sender([[7, 8]])
    assert s.current() == (1, [7, 8])
    assert s.on_ack(1)
    assert s.current() == (LAST, [])


def test_note_example_counter_by_counter():
    """Section 2.1.1: five records, record 2 lost once on the way."""
    r = Receiver()
    s = Sender([[n] * 3 for n in range(5)])
    acks, ack = [], 0
    lost_once = {2}
    while not s.done:
        s.on_ack(ack)
        cur = s.current()
        if cur is None:
            break
        number, payload = cur
        if number in lost_once:
            lost_once.discard(number)
        else:
            ack = r.on_record(number, payload)
        acks.append(ack)
    assert acks == [1, 1, 2, 3, 4, LAST]
    assert r.transfers == [[[n] * 3 for n in range(5)]]


def test_receiver_discards_duplicates_and_ignores_the_unexpected():
    r = Receiver()
    assert r.on_record(1, [1]) == 1
    assert r.on_record(1, [1]) == 1 and r.duplicates == 1
    assert r.on_record(5, [5]) == 1 and r.unexpected == 1
    assert r.on_record(2, [2]) == 2
    assert r.current == [[1], [2]]


def test_sender_restart_mid_transfer_is_reported_not_merged():
    r = Receiver()
    r.on_record(1, [1])
    r.on_record(2, [2])
    assert r.on_record(1, [9]) == 1
    assert r.aborted == [[[1], [2]]]
    assert r.current == [[9]]


def test_receiver_restart_sends_the_whole_transfer_again_and_counts_it():
    s = Sender([[1], [2], [3], [4]])
    assert s.on_ack(1) and s.on_ack(2)
    assert s.on_ack(0)  # receiver forgot everything, also what it accepted before
    assert s.current() == (1, [1]) and s.peer_resets == 1
    assert s.on_ack(1) and s.on_ack(2) and s.on_ack(3)
    assert s.current() == (LAST, [4])


def test_central_answers_the_reset_record_with_zero():
    """Uni layout, spontaneous: a restarted sender's record 0 must be acknowledged at once."""
    cen = Peer("central", layout="uni", drive="spontaneous")
    assert cen.step(0.0, [1, 2, 1, 11]) == [1]
    assert cen.step(0.1, [1, 1, 0]) == [0]
    assert cen.receiver.aborted == [[[11]]]


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


@pytest.mark.parametrize("layout", ["uni", "bi"])
@pytest.mark.parametrize("drive", ["polled", "spontaneous"])
@pytest.mark.parametrize("seed", range(5))
def test_exactly_once_over_a_lossy_link(layout, drive, seed):
    rng = random.Random(seed)
    up = [[rng.randrange(65536) for _ in range(rng.randrange(1, 20))] for _ in range(12)]
    down = [[rng.randrange(65536) for _ in range(5)] for _ in range(4)] if layout == "bi" else None
    out = Peer("outstation", up, layout=layout, drive=drive, retransmit_s=3, request_s=2)
    cen = Peer("central", down, layout=layout, drive=drive, retransmit_s=3, request_s=2)
    link = LossyLink(rng, 0.3)
    for t in range(5000):
        for side, peer in (("outstation", out), ("central", cen)):
            block = peer.step(t, link.read(side))
            if block is not None:
                link.write(side, block)
        link.poll()
        if cen.receiver.transfers and (down is None or out.receiver.transfers):
            break
    assert cen.receiver.transfers == [up]
    if down is not None:
        assert out.receiver.transfers == [down]


def test_record_zero_resets_an_open_transfer_and_is_reported():
    r = Receiver()
    r.on_record(1, [1])
    assert r.on_record(0, []) == 0
    assert r.aborted == [[[1]]]
    assert r.on_record(1, [5]) == 1 and r.current == [[5]]


def test_record_zero_after_a_complete_transfer_only_forgets_it():
    r = Receiver()
    r.on_record(1, [1])
    r.on_record(LAST, [2])
    assert r.on_record(0, []) == 0
    assert r.aborted == [] and r.transfers == [[[1], [2]]]
