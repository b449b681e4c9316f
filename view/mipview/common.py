"""What both kinds of session share: the docs' chain and diagram (mipdocs: one of each),
st_lib's enum names, the diagram of a trace (its rows: rows.py), the error a user sees."""
from __future__ import annotations

from pathlib import Path

from mipcosim.kernel import MS as MS  # re-exported to the view's modules
from mipcosim.programs import st_enums
from mipdocs import chainsim
# re-exported to follow.py and session.py (the redundant alias says so to ruff)
from mipdocs import seqdiag as seqdiag

from .rows import row_data, rows_of

REPO = Path(__file__).resolve().parents[2]

ENUMS = st_enums(chainsim.LIB_DIR / "core" / "MIP_Types.st")


class ViewError(Exception):
    """A bad option or control (one line for the user)."""


def enum_name(type_name, value):
    names = ENUMS[type_name]
    return names[value] if 0 <= value < len(names) else f"{type_name}#{value}"


def diagram(history, events, title, station=1):
    """What the page shows of a trace's diagram: the whole history in chunks (rows.History),
    the last chunk's SVG and rows inline (the page fetches the others by key)."""
    rows = rows_of(events, station)
    chunks = history.update(rows, title)
    last = chunks[-1]
    return {"svg": history.svg(last["i"]), "chunks": chunks, "nrows": len(rows),
            "rows": row_data(rows[(last["first"] or 1) - 1:])}
