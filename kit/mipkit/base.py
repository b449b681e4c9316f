"""What every part of the kit shares: its errors and warnings, time units, the radios, and the
type of the scan callback a stand-in hooks into the kernel's lockstep loop."""
from __future__ import annotations

from mipcosim.kernel import MS, SCAN_FN, SEC  # noqa: F401 (the kit's names for them)

RESPONSE_MAX = 300
REALISTIC = {"bitrate": 9600, "slot_gap_ms": 20, "overhead_bytes": 12}
FAST = {"bitrate": 1_000_000, "slot_gap_ms": 1, "overhead_bytes": 12}


class KitError(Exception):
    """A mistake in what the test or scenario asks for; str() is one line."""


class KitWarning(UserWarning):
    """Something the kit does not stop for but says, in one line: stc's portability warnings
    (once per build), a config key the kit does not follow."""


def _warn(line):
    import warnings
    warnings.warn(KitWarning(line), stacklevel=3)
