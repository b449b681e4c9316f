"""Diagnostics: `FILE:LINE:COL: error: message`, collected so every error of a file is reported."""


class CompileError(Exception):
    """Raised to abandon one construct after its error has been recorded."""


class Diagnostics:
    def __init__(self):
        self.errors = []          # (file, line, col, message)
        self._seen = set()

    def error(self, file, pos, message):
        line, col = pos if pos else (0, 0)
        key = (file, line, col, message)
        if key in self._seen:
            return
        self._seen.add(key)
        self.errors.append(key)

    def __bool__(self):
        return bool(self.errors)

    def format(self):
        out = []
        order = {}
        for e in self.errors:
            order.setdefault(e[0], len(order))
        for file, line, col, msg in sorted(self.errors, key=lambda e: (order[e[0]], e[1], e[2])):
            if line:
                out.append(f"{file}:{line}:{col}: error: {msg}")
            else:
                out.append(f"{file}: error: {msg}")
        return out
