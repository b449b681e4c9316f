"""A trace file read as it grows (read-only): what the page shows of it."""
from __future__ import annotations

import gzip
import json
import zlib
from pathlib import Path

from .common import MS, ViewError, diagram, seqdiag
from .chainview import ChainFiles, merged
from .rows import History

BAD_SHOWN = 50           # bad lines listed on the page and logged (our choice), the rest counted


def radio_counts(events, station=1):
    """Telegrams and lost telegrams per direction, counted from the trace's radio lines."""
    c = {"down": 0, "up": 0, "lost_down": 0, "lost_up": 0}
    for d in events:
        if d.get("ev") == "radio" and d.get("dir") in ("down", "up") and d.get("st") == station:
            c[d["dir"]] += 1
            c["lost_" + d["dir"]] += bool(d.get("lost"))
    return c


class Follow:
    """A trace file (mip-emulator --trace, mipsim --trace, mip-cosim run --trace, the demo's,
    the test kit's) read as it grows: read-only, for commissioning and post-mortems. A .gz
    file (the kit's report keeps the trace around a fault so) is read once; station: whose
    telegrams the diagram shows."""

    mode = "follow"

    def __init__(self, path, station=1, wait=False, log=None, on_bad=None):
        """wait: the file may not exist yet (a run that is starting); log: a file whose last
        line the page shows (the demo's progress); on_bad: called with the one line that says
        why a line of the trace was skipped (a byte that is not UTF-8, no JSON, no trace
        line), which the page shows too; the lines after it are read on."""
        self.path = Path(path)
        self.wait = wait
        self.log = Path(log) if log else None
        if not wait and not self.path.is_file():
            raise ViewError(f"{path}: no such trace file")
        if not 1 <= station <= 247:
            raise ViewError("station must be 1..247")
        self.station = station
        self.events = []
        self.history = History()
        # the chain demo's run directory: its relay and SCADA beside the trace (chainview.py),
        # read once the trace has lines (poll): before, the files may be an earlier run's
        self.ends = None
        self._pos = 0
        self._partial = b""
        self._n = 0
        self.paused = False
        self.speed = 1.0
        self.bad = None         # the first line that is no trace line (file:line: why)
        self.bad_lines = []     # the first BAD_SHOWN of them, each one line on the page
        self.bad_count = 0
        self.on_bad = on_bad    # called with each such line (the server logs it)
        self._note = None
        self.poll()

    def poll(self):
        """Reads what was appended since the last call; True if anything new (the trace or
        the log's last line)."""
        note = self._last_log_line()
        new_note, self._note = note != self._note, note
        new = self._poll_trace()
        if self.ends is None and self.events and ChainFiles.present(self.path):
            self.ends = ChainFiles(self.path)      # the chain demo (--demo "--chain") started
        if self.ends is not None:
            new = self.ends.poll(self.events[-1]["t"] if self.events else 0) or new
        return new or new_note

    def _poll_trace(self):
        if self.path.suffix == ".gz":
            if self._pos:
                return False
            try:
                with gzip.open(self.path, "rb") as f:
                    chunk = f.read() + b"\n"
            except (OSError, EOFError, zlib.error) as e:
                self._bad_line(f"{self.path}: {getattr(e, 'strerror', None) or e}")
                return False
            self._pos = 1
            return self._lines(chunk)
        if self.wait and not self.path.exists():
            return False
        try:
            with open(self.path, "rb") as f:
                f.seek(0, 2)
                if f.tell() < self._pos:            # truncated, a new run: start over
                    self.events, self._pos, self._partial, self._n = [], 0, b"", 0
                    self.bad, self.bad_lines, self.bad_count = None, [], 0
                    self.ends = None        # the new run's files (read again when present)
                f.seek(self._pos)
                chunk = f.read()
                self._pos = f.tell()
        except OSError as e:
            if self.bad != f"{self.path}: {e.strerror}":
                self._bad_line(f"{self.path}: {e.strerror}")
            return False
        if not chunk:
            return False
        return self._lines(chunk)

    def _lines(self, chunk):
        data = self._partial + chunk
        lines = data.split(b"\n")
        self._partial = lines.pop()              # a line still being written
        for raw in lines:
            self._n += 1
            if not raw.strip():
                continue
            why = self._check(raw)
            if isinstance(why, str):
                self._bad_line(why)
            else:
                self.events.append(why)
        return True

    def _check(self, raw):
        """The trace line (a dict) or why it is none (one line, file:line:column: ...)."""
        where = f"{self.path}:{self._n}"
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            return (f"{where}:{e.start + 1}: not UTF-8 (byte 16#{raw[e.start]:02X}): "
                    f"line skipped")
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            return f"{where}:{e.colno}: not a JSON line: {e.msg}"
        except (ValueError, RecursionError) as e:
            return f"{where}:1: not a JSON line: {e}"
        if not isinstance(d, dict) or "ev" not in d or not isinstance(d.get("t"), int) \
                or isinstance(d["t"], bool) or d["t"] < 0:
            return f"{where}:1: a trace line needs \"t\" (ns, an integer >= 0) and \"ev\""
        try:                                     # a field the diagram cannot read
            seqdiag.rows_from([d], self.station, 0, 1 << 62)
        except (TypeError, ValueError, KeyError, AttributeError) as e:
            return f"{where}:1: a field of the wrong type ({type(e).__name__}: {e})"
        return d

    def _bad_line(self, why):
        """One line on the page and in the log (the first BAD_SHOWN; then a count: a file
        that is no trace at all does not flood the log)."""
        self.bad_count += 1
        if self.bad is None:
            self.bad = why
        if len(self.bad_lines) < BAD_SHOWN:
            self.bad_lines.append(why)
            if self.on_bad:
                self.on_bad(why)
        elif self.bad_count == BAD_SHOWN + 1 and self.on_bad:
            self.on_bad(f"{self.path}: more than {BAD_SHOWN} lines skipped: the rest are "
                        f"counted on the page, not logged")

    @property
    def t_ms(self):
        return self.events[-1]["t"] // MS if self.events else 0

    def state(self):
        dg = diagram(self.history, merged(self.events, self.ends),
                     f"{self.path.name}, station {self.station} "
                     f"(following)", self.station)
        return {"mode": self.mode, "title": str(self.path), "t_ms": self.t_ms,
                "paused": self.paused, **dg,
                "radio": radio_counts(self.events, self.station), "lines": len(self.events),
                "note": self._note,
                "bad": self.bad, "bad_lines": self.bad_lines, "bad_count": self.bad_count, "registers": [], "blocks": [], "done": False}

    def _last_log_line(self):
        if self.log is None:
            return None
        try:
            text = self.log.read_text(errors="replace")
        except OSError:
            return None
        # the demo redraws its progress line with carriage returns
        lines = [x.strip() for x in text.replace("\r", "\n").splitlines() if x.strip()]
        return lines[-1] if lines else None

    def close(self):
        pass
