"""What every part of the kit shares: its errors and warnings, time units, the radios, and the
type of the scan callback a stand-in hooks into the kernel's lockstep loop."""
from __future__ import annotations

import ctypes

MS = 1_000_000
SEC = 1_000_000_000
RESPONSE_MAX = 300
SCAN_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_uint64)
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
