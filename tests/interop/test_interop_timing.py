"""The read-out timing figures (interop/mipinterop/timing.py, bench lines `readout_realistic`
and `record_reaction`): what they read from an emulator trace, on hand-made traces whose answer
is known, and one short real read-out per pairing on the fast radio (no figure is checked
against a target here: that is the bench's job)."""
import json

import pytest

from mipcosim.kernel import MS
from mipinterop import timing as T
from mipinterop.matrix import MatrixError


def _trace(tmp_path, events):
    p = tmp_path / "trace.jsonl"
    p.write_text("".join(json.dumps(e) + "\n" for e in events))
    return p


def _mb(t, fc, **kw):
    return {"t": t * MS, "ev": "modbus", "ep": "trm", "st": 1, "fc": fc, "exc": 0, **kw}


def _down(t, r0, air=10):
    return {"t": t * MS, "t0": (t - air) * MS, "ev": "radio", "kind": "poll", "dir": "down",
            "st": 1, "regs": 3, "r0": r0, "lost": False}


def _up(t0, r0, air=200):
    return {"t": (t0 + air) * MS, "t0": t0 * MS, "ev": "radio", "kind": "answer", "dir": "up",
            "st": 1, "regs": 123, "r0": r0, "lost": False}


def test_figures_of_a_known_two_record_readout(tmp_path):
    ev = [
        _mb(100, 3, ra=2198, rq=125),                 # the sender's first request: start
        _mb(110, 16, wa=2001, wq=123, w0=1),          # record 1, 10 ms after the start
        _up(150, 1),                                  # waits 40 ms for its poll slot
        _down(400, 1),                                # acknowledgement 1 arrives at 400
        _mb(405, 3, ra=2198, rq=125),                 # read 5 ms later
        _mb(425, 16, wa=2001, wq=123, w0=0xFFFF),     # next record 20 ms after the read
        _up(480, 0xFFFF),
        _down(800, 0xFFFF, air=14),                   # done at 800
    ]
    r = T.analyse(_trace(tmp_path, ev), "ours->ours", "realistic", 2)
    assert r.record1_s == pytest.approx(0.010)
    assert r.done_s == pytest.approx(0.700)
    assert r.slot_wait_s == pytest.approx(0.040)
    assert r.readout_s == pytest.approx(0.660)
    assert r.reaction_ms == [pytest.approx(20.0)]
    assert r.per_record_ms == pytest.approx(690.0)
    assert r.ack_air_ms == pytest.approx(12.0)


def test_a_lost_acknowledgement_is_not_counted_as_arrived(tmp_path):
    lost = dict(_down(400, 1), lost=True)
    ev = [_mb(0, 16, wa=2001, wq=123, w0=1), _up(10, 1), lost,
          _mb(410, 16, wa=2001, wq=123, w0=0xFFFF)]
    with pytest.raises(MatrixError, match="record 65535 did not follow the acknowledgement 1"):
        T.analyse(_trace(tmp_path, ev), "ours->ours", "fast", 2)


def test_a_readout_that_never_started_says_so(tmp_path):
    with pytest.raises(MatrixError, match="never talked to its modem"):
        T.analyse(_trace(tmp_path, [_down(10, 0)]), "note->note", "fast", 2)


def test_unknown_pair_is_refused(tmp_path):
    with pytest.raises(ValueError, match="one of note->note"):
        T.readout("ours->nobody", "fast", 2, tmp_path)


@pytest.fixture(scope="module")
def progs(tmp_path_factory):
    from mipinterop.matrix import build_programs
    return build_programs(tmp_path_factory.mktemp("timing") / "build")


@pytest.mark.parametrize("pair", T.PAIRS)
def test_every_pairing_completes_a_readout_on_the_fast_radio(pair, progs, tmp_path):
    r = T.readout(pair, "fast", 4, tmp_path, progs=progs)
    # record 1 opens the session in one round trip: no reset record, no quiet wait first
    assert r.record1_s < 0.5, r
    assert r.done_s > r.record1_s
    assert len(r.reaction_ms) == 3
