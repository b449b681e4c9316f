"""What both kinds of session share: the docs' tools on the path (one chain, one diagram),
st_lib's enum names, the diagram of a trace, the error a user sees."""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "docs" / "tools"
if str(TOOLS) not in sys.path:
    sys.path.insert(0, str(TOOLS))          # the docs' chain and diagram, one copy of each

import chainsim  # noqa: E402
import seqdiag  # noqa: E402
from chainsim import MS  # noqa: E402
from mipcosim.layout import st_enums  # noqa: E402

ENUMS = st_enums(chainsim.LIB_DIR / "MIP_Types.st")
ROWS_SHOWN = 36                      # rows of the diagram on the page (our choice: one screen)


class ViewError(Exception):
    """A bad option or control (one line for the user)."""


def enum_name(type_name, value):
    names = ENUMS[type_name]
    return names[value] if 0 <= value < len(names) else f"{type_name}#{value}"


def diagram(events, title, station=1):
    """The seqdiag rows of a trace (one station's) and the SVG of the last ROWS_SHOWN."""
    rows = seqdiag.rows_from(events, station, 0, 1 << 62)
    shown = rows[-ROWS_SHOWN:]
    caption = (f"The last {len(shown)} of {len(rows)} rows; empty polls and answers and PLC reads "
               f"without new data omitted.")
    svg = seqdiag.render(shown, title, caption)
    return svg, [{"t_ms": t // MS, "kind": kind, "text": d.get("text", ""),
                  "lost": bool(d.get("lost"))} for t, kind, d in shown], len(rows)
