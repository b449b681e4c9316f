"""Where an offset of a source text is: (line, column), both 1-based, as stc's messages give
them. Shared by the dialect front ends (scl_in, vendor_in), which rewrite a text in place and
report errors at offsets of the original."""
from __future__ import annotations

import bisect


def line_col(text: str):
    """A function offset -> (line, column) for `text`."""
    starts = [0] + [i + 1 for i, ch in enumerate(text) if ch == "\n"]

    def where(off: int) -> tuple[int, int]:
        k = bisect.bisect_right(starts, off) - 1
        return (k + 1, off - starts[k] + 1)
    return where
