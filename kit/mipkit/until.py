"""What Net.run_until returns: true when the condition held in time; false otherwise, and then
an assertion on it reads what did not happen (`assert <not within 120 s: ...>`), not
`assert False` (issue 44)."""
from __future__ import annotations


class Until:
    def __init__(self, ok: bool, within_s: float, now_s: float):
        self.ok, self.within_s, self.now_s = bool(ok), within_s, now_s

    def __bool__(self):
        return self.ok

    def __eq__(self, other):
        return self.ok == other

    def __hash__(self):
        return hash(self.ok)

    def __repr__(self):
        if self.ok:
            return "True"
        return (f"<not within {self.within_s:g} s: the condition was still false at "
                f"{self.now_s:.3f} s of virtual time>")
