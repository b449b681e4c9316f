#!/usr/bin/env python3
"""plc/gen_programs.py: writes the example programs of plc/ (the generator is mipprograms.gen;
`python -m mipprograms.gen` is the same command). Options: --help."""
import sys

try:
    from mipprograms.gen import main
except ModuleNotFoundError as e:     # a python3 without the checkout's packages
    sys.exit(f"gen_programs.py: error: module {e.name!r} not found: run it with the checkout's "
             "venv (make; .venv/bin/python plc/gen_programs.py ...)")

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
