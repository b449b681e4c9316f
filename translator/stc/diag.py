"""Diagnostics: `FILE:LINE:COL: error: message [CODE]`, collected so every error of a file is
reported. Every diagnostic has a code from the one table, problems.csv (stc/problems.py)."""


class CompileError(Exception):
    """Raised to abandon one construct after its error has been recorded."""


class Diagnostics:
    def __init__(self):
        self.errors = []          # (file, line, col, message, code)
        self.warnings = []        # (file, line, col, message, code): portability warnings
        self._seen = set()

    def warn(self, file, pos, message, code=None):
        self._add(self.warnings, file, pos, message, code)

    def error(self, file, pos, message, code=None):
        self._add(self.errors, file, pos, message, code)

    def _add(self, into, file, pos, message, code):
        """One message once: the same text at the same place is reported the first time."""
        line, col = pos if pos else (0, 0)
        key = (file, line, col, message)
        if key in self._seen:
            return
        self._seen.add(key)
        into.append((file, line, col, message, code))

    def __bool__(self):
        return bool(self.errors)

    def format(self, warnings=False):
        out = []
        order = {}
        items = self.warnings if warnings else self.errors
        kind = "warning" if warnings else "error"
        for e in items:
            order.setdefault(e[0], len(order))
        for file, line, col, msg, code in sorted(items, key=lambda e: (order[e[0]], e[1], e[2])):
            tail = f" [{code}]" if code else ""
            if line:
                out.append(f"{file}:{line}:{col}: {kind}: {msg}{tail}")
            else:
                out.append(f"{file}: {kind}: {msg}{tail}")
        return out
