"""The matrix's judge, without processes: what it calls complete, what silent loss or
duplication it catches (a judge that passes everything would make the matrix worthless)."""
import pytest

from mipcosim import programs as L
from mipinterop.matrix import Cell, CellRun, Config

WANT = [[n * 100 + j for j in range(5)] for n in range(1, 7)]


def _run(key="receiver/strict/none/uni/dynamic"):
    return CellRun(Cell.parse(key), Config(), progs={}, workdir=None, seed=1)


def _words(stream, transfers=1, open_=()):
    """A receiver's %MW block after committing `stream` (registers), with the registers
    `open_` of a transfer still open after it, as PLC_RecordStore keeps them."""
    w = [0] * (L.W_BASE + L.WINDOW)
    w[L.R_COM_LO], w[L.R_COM_HI] = len(stream) % 65536, len(stream) // 65536
    w[L.R_OPEN_LO], w[L.R_OPEN_HI] = len(open_) % 65536, len(open_) // 65536
    w[L.R_SUM_A], w[L.R_SUM_B] = L.fletcher(stream)
    w[L.R_TRANSFERS] = transfers
    for p, v in enumerate(list(stream) + list(open_)):
        w[L.W_BASE + p % L.WINDOW] = v
    return w


def flat(records):
    return [v for r in records for v in r]


def test_our_receiver_holding_the_transfer_once_is_held():
    assert _run().plc_stream_state(_words(flat(WANT)), WANT, False) == ("held", "")
    assert _run().plc_stream_state(_words([]), WANT, False)[0] == "pending"


@pytest.mark.parametrize("records, why", [
    (WANT[:1] + WANT[2:], "not whole transfers"),                  # a record lost
    (WANT[:2] + WANT[1:2] + WANT[2:5], "register"),                # one twice, the last missing
    ([WANT[2]] + WANT[1:], "register 0 (record 1"),                # the mix the matrix found
])
def test_our_receiver_silent_loss_or_mix_is_bad(records, why):
    state, text = _run().plc_stream_state(_words(flat(records)), WANT, False)
    assert state == "bad" and why in text


def test_a_whole_second_transfer_is_bad_unless_its_sender_restarted():
    w = _words(flat(WANT) * 2, transfers=2)
    assert _run().plc_stream_state(w, WANT, False) == ("bad", "our receiver committed the transfer 2 times")
    assert _run().plc_stream_state(w, WANT, True) == ("held", "")


def test_an_open_resend_after_a_complete_transfer_is_not_read_as_committed():
    # CI found it: the restarted peer sent its 6 x 20 registers again; records 1..4 of the
    # resend were open in the ring after the 120 committed registers, and record 3 had wrapped
    # onto position 0. The committed positions it overwrote are not compared; the rest are.
    want = [[n * 1000 + j for j in range(20)] for n in range(1, 7)]
    resend = flat(want[:4])
    w = _words(flat(want), open_=resend)
    assert w[L.W_BASE] == want[2][0]              # the ring did wrap
    assert _run().plc_stream_state(w, want, True) == ("held", "")
    w[L.W_BASE + 119] ^= 1                        # the last committed register, not overwritten
    state, text = _run().plc_stream_state(w, want, True)
    assert state == "bad" and "register 119 (record 6" in text


def test_the_peer_side():
    r = _run("sender/strict/none/uni/dynamic")
    assert r.peer_stream_state({"transfers": [WANT]}, WANT, False) == ("held", "")
    assert r.peer_stream_state({"transfers": []}, WANT, False)[0] == "pending"
    assert r.peer_stream_state({"transfers": [WANT[:5]]}, WANT, False)[0] == "bad"
    assert r.peer_stream_state({"transfers": [WANT, WANT]}, WANT, False)[0] == "bad"
    assert r.peer_stream_state({"transfers": [WANT, WANT]}, WANT, True) == ("held", "")


def test_cell_keys_round_trip_and_bad_keys_are_named():
    assert Cell.parse("receiver/lenient/restart-peer/bi/static").key == \
        "receiver/lenient/restart-peer/bi/static"
    with pytest.raises(ValueError, match="'sideways' is not one of uni, bi"):
        Cell.parse("sender/strict/none/sideways/static")
