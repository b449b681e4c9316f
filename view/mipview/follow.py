"""A trace file read as it grows (read-only): what the page shows of it."""
from __future__ import annotations

import gzip
import json
from pathlib import Path

from .common import MS, ViewError, diagram


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

    def __init__(self, path, station=1, wait=False, log=None):
        """wait: the file may not exist yet (a run that is starting); log: a file whose last
        line the page shows (the demo's progress)."""
        self.path = Path(path)
        self.wait = wait
        self.log = Path(log) if log else None
        if not wait and not self.path.is_file():
            raise ViewError(f"{path}: no such trace file")
        if not 1 <= station <= 247:
            raise ViewError("station must be 1..247")
        self.station = station
        self.events = []
        self._pos = 0
        self._partial = b""
        self._n = 0
        self.paused = False
        self.speed = 1.0
        self.bad = None         # the first line that is no trace line (file:line: why)
        self._note = None
        self.poll()

    def poll(self):
        """Reads what was appended since the last call; True if anything new (the trace or
        the log's last line)."""
        note = self._last_log_line()
        new_note, self._note = note != self._note, note
        return self._poll_trace() or new_note

    def _poll_trace(self):
        if self.path.suffix == ".gz":
            if self._pos:
                return False
            try:
                with gzip.open(self.path, "rb") as f:
                    chunk = f.read() + b"\n"
            except (OSError, EOFError) as e:
                self.bad = f"{self.path}: {getattr(e, 'strerror', None) or e}"
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
                f.seek(self._pos)
                chunk = f.read()
                self._pos = f.tell()
        except OSError as e:
            self.bad = f"{self.path}: {e.strerror}"
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
            try:
                d = json.loads(raw)
            except json.JSONDecodeError as e:
                self.bad = self.bad or f"{self.path}:{self._n}:{e.colno}: not a JSON line: {e.msg}"
                continue
            if not isinstance(d, dict) or not isinstance(d.get("t"), int) or "ev" not in d:
                self.bad = self.bad or f"{self.path}:{self._n}:1: a trace line needs \"t\" and \"ev\""
                continue
            self.events.append(d)
        return True

    @property
    def t_ms(self):
        return self.events[-1]["t"] // MS if self.events else 0

    def state(self):
        svg, rows, nrows = diagram(self.events, f"{self.path.name}, station {self.station} "
                                   f"(following)", self.station)
        return {"mode": self.mode, "title": str(self.path), "t_ms": self.t_ms,
                "paused": self.paused, "svg": svg, "rows": rows, "nrows": nrows,
                "radio": radio_counts(self.events, self.station), "lines": len(self.events),
                "note": self._note,
                "bad": self.bad, "registers": [], "blocks": [], "done": False}

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
