#!/usr/bin/env python3
"""plc/demo.py: the demo of `make run` (mipdemo; `python -m mipdemo` is the same command).
Options: --help; --chain --help for the chain's."""
import sys

from mipdemo.cli import main
# Until interop/mipinterop/matrix.py imports mipdemo.common (it still puts plc/ on sys.path and
# imports this file as `demo`): the names it uses. Delete with that sys.path edit.
from mipdemo.common import DemoError, Procs, Slave, TraceStats, free_port  # noqa: F401

if __name__ == "__main__":
    sys.exit(main())
