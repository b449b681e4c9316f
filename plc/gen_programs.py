#!/usr/bin/env python3
"""plc/gen_programs.py: writes the example programs of plc/ (the generator is mipprograms.gen;
`python -m mipprograms.gen` is the same command). Options: --help."""
import sys

from mipprograms.gen import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
