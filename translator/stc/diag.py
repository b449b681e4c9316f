"""Diagnostics: `FILE:LINE:COL: error: message`, collected so every error of a file is reported."""


class CompileError(Exception):
    """Raised to abandon one construct after its error has been recorded."""


class Diagnostics:
    def __init__(self):
        self.errors = []          # (file, line, col, message)
        self.warnings = []        # (file, line, col, message): portability warnings
        self._seen = set()

    def warn(self, file, pos, message):
        self._add(self.warnings, file, pos, message)

    def error(self, file, pos, message):
        self._add(self.errors, file, pos, message)

    def _add(self, into, file, pos, message):
        """One message once: the same text at the same place is reported the first time."""
        line, col = pos if pos else (0, 0)
        key = (file, line, col, message)
        if key in self._seen:
            return
        self._seen.add(key)
        into.append(key)

    def __bool__(self):
        return bool(self.errors)

    def format(self, warnings=False):
        out = []
        order = {}
        items = self.warnings if warnings else self.errors
        kind = "warning" if warnings else "error"
        for e in items:
            order.setdefault(e[0], len(order))
        for file, line, col, msg in sorted(items, key=lambda e: (order[e[0]], e[1], e[2])):
            if line:
                out.append(f"{file}:{line}:{col}: {kind}: {msg}")
            else:
                out.append(f"{file}: {kind}: {msg}")
        return out
