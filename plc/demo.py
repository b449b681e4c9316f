#!/usr/bin/env python3
"""plc/demo.py: the demo of `make run` (mipdemo; `python -m mipdemo` is the same command).
Options: --help; --chain --help for the chain's."""
import sys

from mipdemo.cli import main

if __name__ == "__main__":
    sys.exit(main())
