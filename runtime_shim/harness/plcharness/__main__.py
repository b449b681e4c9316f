"""python -m plcharness -o OUTDIR [--compiler ...] FILE.st... (same as plcrt-build)."""
import sys

from .build import main

sys.exit(main())
