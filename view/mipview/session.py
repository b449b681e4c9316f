"""What the page shows and what its controls do, without the web server: a live run of the
docs' chain (docs/tools/chainsim.py: the st_lib blocks in two soft PLCs and the emulator core in
the co-simulation kernel, stepped one scan tick at a time) or a trace file followed as it grows.

Both produce one state (`state()`, a dict the page draws): the sequence diagram of the whole
run in chunks (docs/tools/seqdiag.py: the same rows and drawing as the docs' pictures, with the
counters in the note's words and the repeats marked, rows.py), the modems' register
windows with the registers changed since the previous state, the blocks' states and counters
under the names of st_lib's enums (read from st_lib/core/MIP_Types.st), and the radio's counters.
Nothing here models the link a second time: the live run is chainsim's Chain, the trace is
the emulator's own.
"""
from __future__ import annotations

# the parts (common, presets, live, follow), under the one name the server and the tests use
from .common import ENUMS, MS, REPO, ViewError, diagram, enum_name, seqdiag  # noqa: F401
from mipdocs.chainsim import ChainError  # noqa: F401
from .follow import Follow, radio_counts  # noqa: F401
from .live import SPEEDS, WINDOWS, Live  # noqa: F401
from .presets import PRESETS, Preset  # noqa: F401
from .rows import CHUNK, History, note_words, rows_of  # noqa: F401


CHAINS = {"chain": "pull", "chain-push": "push"}   # the whole chain's runs (chainview.py)


def make_live(name, workdir=None):
    """The live run of a preset, or of the whole chain (the SCADA polls it: pull; or it
    pushes to WinCC OA's drivers: push)."""
    if name in CHAINS:
        from .chainview import ChainLive
        return ChainLive(workdir, handover=CHAINS[name])
    return Live(name, workdir)
