"""The one reader of the emulator's trace: JSON lines, one event a line, each an object with
"t" (the trace's time in ns, a non-negative integer) and "ev" (what happened: "modbus",
"radio", "plc", "relay", ...). The emulator, the co-simulation kernel and the relay write it
(fields: emulator/README.md); the docs' tools, the view, the kit, the bench, interop and the
tests read it here.

    read_trace(path)    the events of a trace file, in order
    parse(lines, path)  the events of trace lines already in memory (a kernel's trace())

A line that is not a trace line is an error of one line, file:line:column (TraceError); blank
lines are skipped. A reader that follows a file while it is being written (the view, the kit's
reports, the demo's counters) skips a partial last line instead: that is their own loop.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Iterable


class TraceError(ValueError):
    """A line that is not a trace line, or a trace that cannot be read: one line of text."""


def parse(lines: Iterable[str], path: str | Path = "-", line_numbers: bool = False) -> list[dict]:
    """The events of `lines` (line n of `path` is the n-th item, for the messages); with
    line_numbers, each event also gets "_line": its line number (a diagram that names it)."""
    events = []
    for n, line in enumerate(lines, 1):
        line = line.strip()
        if not line:
            continue
        try:
            d = json.loads(line)
        except json.JSONDecodeError as e:
            raise TraceError(f"{path}:{n}:{e.colno}: error: not a JSON line: {e.msg}") from None
        if not isinstance(d, dict) or "t" not in d or "ev" not in d:
            raise TraceError(f"{path}:{n}:1: error: a trace line needs \"t\" and \"ev\"")
        if not isinstance(d["t"], int) or isinstance(d["t"], bool) or d["t"] < 0:
            raise TraceError(f"{path}:{n}:1: error: \"t\" must be a non-negative integer (ns)")
        if line_numbers:
            d["_line"] = n
        events.append(d)
    return events


def read_trace(path: str | Path, line_numbers: bool = False, prog: str | None = None) -> list[dict]:
    """The events of the trace file `path` ("-": standard input). A file that cannot be opened is
    a TraceError "PROG: error: PATH: why" (prog: the command that reads it, if any)."""
    try:
        f = sys.stdin if str(path) == "-" else open(path, encoding="utf-8")
    except OSError as e:
        raise TraceError(f"{prog + ': ' if prog else ''}error: {path}: {e.strerror}") from None
    with f:
        return parse(f, path, line_numbers)
