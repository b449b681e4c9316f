"""The project's convention for a command line tool's errors: one line on stderr, never a
traceback (`PROG: error: WHERE: REASON`, or the tool's own `FILE:LINE:COL: error: ...` line as
it is), and exit status 1. The translator is the lowest layer, so the tools of every part
(stc, dist/mkdist.py, docs/tools, the view) take it from here."""
from __future__ import annotations

import os
import sys


def run(prog, step, *, where=None, errors=(), located=()):
    """step() -> its exit status (None counts as 0). An OSError becomes `PROG: error: WHERE:
    REASON` (WHERE: the where given, else the file the error names; REASON: the system's
    words); an exception of errors `PROG: error: TEXT`; one of located (whose text already is
    the whole line, e.g. `FILE:LINE: error: ...`) is printed as it is. All three return 1."""
    try:
        status = step()
    except located as e:
        print(e, file=sys.stderr)
        return 1
    except errors as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        place = where if where is not None else e.filename
        reason = e.strerror or str(e)
        print(f"{prog}: error: {place}: {reason}" if place else f"{prog}: error: {reason}",
              file=sys.stderr)
        return 1
    return 0 if status is None else status


def write_output(prog, path, text, *, status=0, make_dir=False):
    """Write text (UTF-8) to the file path, and its directory first with make_dir; returns
    status, or 1 after the one line `PROG: error: PATH: REASON` when it cannot be written."""
    def write():
        if make_dir:
            os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    return run(prog, write, where=path) or status
