#!/usr/bin/env python3
"""plc/openplc_limits.py MBCONFIG.cfg...: refuses an OpenPLC v3 mbconfig.cfg over stock
OpenPLC's limits (mipprograms.openplc_limits; `python -m mipprograms.openplc_limits` is the
same command)."""
import sys

from mipprograms.openplc_limits import main

if __name__ == "__main__":
    sys.exit(main())
