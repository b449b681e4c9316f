#!/usr/bin/env python3
"""plc/demo.py: the demo of `make run` (mipdemo; `python -m mipdemo` is the same command).
Options: --help; --chain --help for the chain's."""
import sys

try:
    from mipdemo.cli import main
except ModuleNotFoundError as e:     # a python3 without the checkout's packages
    sys.exit(f"demo.py: error: module {e.name!r} not found: run it with the checkout's "
             "venv (make; .venv/bin/python plc/demo.py ...)")

if __name__ == "__main__":
    sys.exit(main())
