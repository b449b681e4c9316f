"""The last line of `mip-cosim run|soak` (with or without --chain): `result: ok ...` or
`result: FAIL <why>`, which scripts and the docs read."""
from __future__ import annotations


def failed(e: BaseException) -> int:
    """Prints the result line of a run that ended in a kernel error or Ctrl-C; the exit code."""
    print("result: FAIL interrupted" if isinstance(e, KeyboardInterrupt) else f"result: FAIL {e}")
    return 1
