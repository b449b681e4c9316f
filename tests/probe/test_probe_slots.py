"""The time slots mip-probe reports (issue 48: "time slots seen"): derived from the arrivals of
the measured blocks (probe/mipprobe/slots.py, our choice: the note shows no slots). Against the
emulator with two slot lengths, the cycle it reports is the emulator's radio model's; over the
fast radio it says that the slots are too fast to tell apart; a block the modem repeated a slot
later is counted as later."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from miptest.emu import Emulator
from mipprobe.slots import slots_seen

PROBE = Path(sys.executable).parent / "mip-probe"
BITRATE = 1_000_000


def air_ms(registers, overhead=12):
    """a telegram's air time, emulator/README.md "Radio model": (overhead + 2 r) * 8 / bitrate"""
    return (overhead + 2 * registers) * 8 * 1000 / BITRATE


def probe_one_station(tmp_path, gap_ms, blocks, *loss):
    """mip-probe of the emulator's one station at BITRATE with gap_ms gaps: its round trips in
    the report, and the round trips line it printed"""
    e = Emulator("--bitrate", BITRATE, "--slot-gap-ms", gap_ms, "--stations", 1, *loss)
    try:
        r = subprocess.run([str(PROBE), "--mdp", f"127.0.0.1:{e.mdp_port}",
                            "--trm", f"1=127.0.0.1:{e.trm_port(1)}", "--watch", "0.2",
                            "--blocks", str(blocks), "--report", tmp_path / "r.json"],
                           capture_output=True, text=True, timeout=120)
    finally:
        assert e.stop() == 0
    assert r.returncode == 0, r.stdout + r.stderr
    rt = json.loads((tmp_path / "r.json").read_text())["stations"][0]["round_trips"]
    return rt, re.search(r"^  ok   round trips   (.*)$", r.stdout, re.M).group(1)


@pytest.mark.parametrize("gap_ms", [50, 120])
def test_the_slot_cycle_is_the_radios(gap_ms, tmp_path):
    """One station, so that its slots follow each other (emulator/README.md "Radio model"): a
    slot that carries a block down is poll (with the block) + gap + answer + gap; one that
    carries a block up is poll + gap + answer (with the block) + gap + ack + gap."""
    want = {"down": air_ms(123) + gap_ms + air_ms(0) + gap_ms,
            "up": air_ms(0) + gap_ms + air_ms(123) + gap_ms + air_ms(0) + gap_ms}
    rt, line = probe_one_station(tmp_path, gap_ms, 4)
    for d in ("down", "up"):
        s = rt[d]["slots"]
        assert s["resolved"] and s["per_block"] == [1, 1, 1] and s["later"] == 0, (d, s)
        # the probe sees an arrival up to a read period (10 ms) and a read late, at both ends
        # of a gap; the two gaps' cycles are 140 ms apart and more
        assert abs(s["cycle_ms"] - want[d]) <= 20, (d, s["cycle_ms"], want[d])
        assert f"{d} " in line and (f"its slot every {s['cycle_ms']:g} ms (of the 3 blocks "
                                    f"after the first, 3 in the next slot, 0 later)") in line


def test_slots_faster_than_the_probe_are_said_to_be():
    """1 ms gaps: every block arrives by the probe's first read after its write (10 ms)."""
    writes = [0.0, 0.03, 0.06, 0.09]
    arrivals = [w + 0.0104 for w in writes]
    s = slots_seen(writes, arrivals, resolution=0.0102)
    assert not s["resolved"] and s["cycle_ms"] is None and s["per_block"] is None


def test_a_block_repeated_a_slot_later_is_counted():
    """Blocks written 40 ms after the previous arrival, slots every 200 ms: the third block was
    lost on air once and the modem sent it again in the slot after (400 ms after the second)."""
    arrivals = [0.2, 0.4, 0.8, 1.0, None, 1.4]
    writes = [0.0] + [a + 0.04 if a is not None else 1.04 for a in arrivals[:-1]]
    s = slots_seen(writes, arrivals, resolution=0.012)
    assert s["resolved"] and s["cycle_ms"] == 200.0
    assert s["per_block"] == [1, 2, 1] and s["later"] == 1   # gaps around the lost block: none


def test_a_lost_poll_shorter_than_a_slot_still_counts_as_later():
    """Slots of 3 gaps up (a block up and its acknowledgement), a lost poll's slot 2: a block
    after a lost poll arrives 1.67 cycles later (emulator/README.md "Radio model")."""
    arrivals = [0.15, 0.30, 0.55, 0.70]
    writes = [0.0] + [a + 0.06 for a in arrivals[:-1]]
    s = slots_seen(writes, arrivals, resolution=0.011)
    assert s["cycle_ms"] == 150.0 and s["per_block"] == [1, 2, 1] and s["later"] == 1


def test_losses_on_air_show_as_later_slots(tmp_path):
    """20 % of the telegrams lost each way: the modems repeat, some blocks take a later slot,
    and the cycle of the blocks that took the next one is still the radio's. (Which telegrams
    are lost follows the real clock, whatever the seed: a block takes the next slot with
    p = 0.8 x 0.8 down, so no down gap of 7 is the cycle once in 1,300 runs, and no gap of 14
    is later once in 2,500.)"""
    gap_ms = 50
    rt, _ = probe_one_station(tmp_path, gap_ms, 8, "--loss-down", 0.2, "--loss-up", 0.2)
    down = rt["down"]["slots"]
    assert abs(down["cycle_ms"] - (air_ms(123) + gap_ms + air_ms(0) + gap_ms)) <= 20, down
    assert rt["down"]["slots"]["later"] + rt["up"]["slots"]["later"] >= 1, rt
