"""Command line: stc [-I DIR]... -o OUTDIR FILE.st..."""
import argparse
import glob
import os
import sys

from . import __version__
from .diag import CompileError, Diagnostics

USAGE_EPILOG = """\
Each -I DIR adds the *.st files of DIR (sorted by name) as library sources: their TYPEs,
FUNCTIONs and FUNCTION_BLOCKs can be used by FILE.st; a CONFIGURATION in them is ignored.
A file given both on the command line and through -I is read once.

Output in OUTDIR: POUS.h, POUS.c, Config0.c, one <RESOURCE>.c per resource, stc_rt.h,
LOCATED_VARIABLES.h, SYMBOLS.tsv and SOURCES.txt (the .c files to compile).
Errors are printed as FILE:LINE:COL: error: MESSAGE. Exit status: 0 success, 1 errors in
the input, 2 bad usage."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        print(f"stc: error: {message}", file=sys.stderr)
        sys.exit(2)


def main(argv=None):
    ap = _Parser(prog="stc", description="Translate IEC 61131-3 Structured Text (matiec dialect) to C.",
                 epilog=USAGE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", dest="outdir", metavar="OUTDIR", help="directory for the generated files")
    ap.add_argument("-I", dest="libdirs", metavar="DIR", action="append", default=[],
                    help="also read the *.st files in DIR as library POUs")
    ap.add_argument("--version", action="version", version=f"stc {__version__}")
    ap.add_argument("files", nargs="*", metavar="FILE.st")
    args = ap.parse_args(argv)
    if not args.files:
        ap.error("no input files")
    if not args.outdir:
        ap.error("missing -o OUTDIR")
    try:
        return run(args.files, args.libdirs, args.outdir)
    except KeyboardInterrupt:
        return 130
    except Exception as e:  # last resort: never show a traceback to the user
        if os.environ.get("STC_DEBUG"):
            raise
        print(f"stc: error: internal: {type(e).__name__}: {e}", file=sys.stderr)
        return 1


def run(files, libdirs, outdir):
    from .compiler import compile_files
    sources = []
    seen = set()
    for f in files:
        rp = os.path.realpath(f)
        if rp in seen:
            continue
        seen.add(rp)
        sources.append((f, False))
    for d in libdirs:
        if not os.path.isdir(d):
            print(f"stc: error: -I {d}: not a directory", file=sys.stderr)
            return 1
        for f in sorted(glob.glob(os.path.join(d, "*.st"))):
            rp = os.path.realpath(f)
            if rp in seen:
                continue
            seen.add(rp)
            sources.append((f, True))
    texts = []
    for f, lib in sources:
        try:
            with open(f, encoding="utf-8", errors="replace") as fh:
                texts.append((f, fh.read(), lib))
        except OSError as e:
            print(f"stc: error: {f}: {e.strerror}", file=sys.stderr)
            return 1
    diags = Diagnostics()
    project = compile_files(texts, diags)
    if diags:
        for line in diags.format():
            print(line, file=sys.stderr)
        return 1
    from .cgen import Gen
    try:
        Gen(project, [f for f, _, _ in texts]).generate(outdir)
    except OSError as e:
        print(f"stc: error: {outdir}: {e.strerror}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
