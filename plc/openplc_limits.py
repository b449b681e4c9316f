#!/usr/bin/env python3
"""plc/openplc_limits.py MBCONFIG.cfg...: refuses an OpenPLC v3 mbconfig.cfg over stock
OpenPLC's limits (mipprograms.openplc_limits; `python -m mipprograms.openplc_limits` is the
same command)."""
import sys

try:
    from mipprograms.openplc_limits import main
except ModuleNotFoundError as e:     # a python3 without the checkout's packages
    sys.exit(f"openplc_limits.py: error: module {e.name!r} not found: run it with the checkout's "
             "venv (make; .venv/bin/python plc/openplc_limits.py ...)")

if __name__ == "__main__":
    sys.exit(main())
