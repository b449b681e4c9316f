"""Command line: stc [-I DIR]... -o OUTDIR FILE.st..."""
import argparse
import glob
import os
import sys
import threading

from . import __version__, oneline
from .diag import Diagnostics
from .semantics import SEMANTICS

USAGE_EPILOG = """\
Each -I DIR adds the *.st files of DIR (sorted by name) as library sources: their TYPEs,
FUNCTIONs and FUNCTION_BLOCKs can be used by FILE.st; a CONFIGURATION in them is ignored.
A file given both on the command line and through -I is read once.

Output in OUTDIR: POUS.h, POUS.c, Config0.c, one <RESOURCE>.c per resource, stc_rt.h,
LOCATED_VARIABLES.h, SYMBOLS.tsv and SOURCES.txt (the .c files to compile).
--semantics=matiec (the default) makes the C reproduce upstream matiec's run-time values
(what Beremiz runs) where they differ from IEC 61131-3; --semantics=openplc those of the
matiec fork OpenPLC v3 ships; --semantics=iec gives the IEC values. Constructs whose value
differs between them get a portability warning (FILE:LINE:COL: warning: MESSAGE) in every
mode; --werror-portability makes them errors.
--strict-iec adds warnings where a strict IEC 61131-3 edition-2 checker rejects what matiec
accepts (an untyped integer literal stored in an ANY_BIT variable: write WORD#0 or 16#0).
--dialect=scl reads the inputs as TIA Portal SCL external sources (#locals, "quoted" block
names, REGION, { attributes }, VERSION, BEGIN, // comments, TON_TIME ...; see
translator/README.md); a FILE.scl is read so without it, and with it -I DIR reads DIR/*.scl.
--dialect=twincat|codesys reads the inputs as the ST of TwinCAT 3 / CODESYS V3 (the vendor
glue: pragmas, // comments, library namespaces, END_IF without ';', POINTER TO, ADR, SIZEOF,
p^, MEMCPY; see translator/README.md); FILE.twincat.st / FILE.codesys.st are read so without it.
Errors are printed as FILE:LINE:COL: error: MESSAGE. Exit status: 0 success, 1 errors in
the input, 2 bad usage."""

# Deeply nested expressions are checked and generated recursively: run the translation in a
# thread with a large stack and a matching recursion limit (the parser itself is iterative,
# and expressions nested deeper than parser.MAX_DEPTH get a located error).
_STACK = 512 * 1024 * 1024
_RECURSION = 60000


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
    ap.add_argument("--semantics", choices=SEMANTICS, default="matiec",
                    help="run-time values to reproduce: upstream matiec's (default), those of "
                         "OpenPLC v3's matiec fork, or IEC 61131-3's")
    ap.add_argument("--werror-portability", action="store_true",
                    help="treat portability warnings (matiec and IEC values differ) as errors")
    ap.add_argument("--strict-iec", action="store_true",
                    help="also warn where a strict IEC 61131-3 edition-2 checker rejects what "
                         "matiec accepts (an untyped integer literal stored in BYTE/WORD/...)")
    ap.add_argument("--divergences", action="store_true",
                    help="also list every construct whose value can differ between upstream "
                         "matiec, OpenPLC's fork and IEC (FILE:LINE:COL: note: KIND: ...), "
                         "warned or not")
    ap.add_argument("--dialect", choices=["st", "scl", "twincat", "codesys"], default=None,
                    help="input language: IEC ST (matiec dialect), TIA Portal SCL, or the ST of "
                         "TwinCAT 3 / CODESYS V3 (pragmas, // comments, library namespaces, "
                         "POINTER TO, ADR, SIZEOF, MEMCPY); default: by file name (*.scl is SCL, "
                         "FILE.twincat.st / FILE.codesys.st the vendor's ST, anything else ST)")
    ap.add_argument("--explain", metavar="CODE",
                    help="print what the diagnostic CODE (the [P0104] / [S0505] / [W0001] at the "
                         "end of a message) means, from stc's table of problems, and exit")
    ap.add_argument("--version", action="version", version=f"stc {__version__}")
    ap.add_argument("files", nargs="*", metavar="FILE.st")
    args = ap.parse_args(argv)
    if args.explain is not None:
        from .problems import explain
        lines = explain(args.explain)
        if lines is None:
            ap.error(f"--explain {args.explain}: no such code (stc's codes: stc/problems.csv)")
        print("\n".join(lines))
        return 0
    if not args.files:
        ap.error("no input files")
    if not args.outdir:
        ap.error("missing -o OUTDIR")
    result = []

    def work():
        try:
            result.append(run(args.files, args.libdirs, args.outdir, args.semantics,
                              args.werror_portability, args.strict_iec, args.divergences,
                              args.dialect))
        except Exception as e:  # last resort: never show a traceback to the user
            if os.environ.get("STC_DEBUG"):
                raise
            print(f"stc: error: internal: {type(e).__name__}: {e}", file=sys.stderr)
            result.append(1)

    try:
        run_deep(work)
    except KeyboardInterrupt:
        return 130
    return result[0] if result else 1


def run_deep(fn):
    """Run fn() in a thread with a large stack and a high recursion limit."""
    old = sys.getrecursionlimit()
    try:
        threading.stack_size(_STACK)
    except (ValueError, RuntimeError):
        fn()
    else:
        sys.setrecursionlimit(max(old, _RECURSION))
        try:
            t = threading.Thread(target=fn, name="stc", daemon=True)
            t.start()
            t.join()
        finally:
            threading.stack_size(0)
            sys.setrecursionlimit(old)


def run(files, libdirs, outdir, semantics="matiec", werror_portability=False, strict_iec=False,
        divergences=False, dialect=None):
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
        for f in sorted(glob.glob(os.path.join(d, "*.scl" if dialect == "scl" else "*.st"))):
            rp = os.path.realpath(f)
            if rp in seen:
                continue
            seen.add(rp)
            sources.append((f, True))
    texts = []
    for f, lib in sources:
        try:
            with open(f, encoding="utf-8-sig", errors="replace") as fh:   # -sig: a BOM (TIA) is read
                texts.append((f, fh.read(), lib))
        except OSError as e:
            print(f"stc: error: {f}: {e.strerror}", file=sys.stderr)
            return 1
    diags = Diagnostics()
    project = compile_files(texts, diags, semantics, strict_iec, dialect)
    for line in diags.format(warnings=True):
        if werror_portability:   # the warnings are what fails the build: say so
            line = line.replace(": warning: ", ": error: ", 1) + " [--werror-portability]"
        print(line, file=sys.stderr)
    if divergences and project is not None:
        seen = set()
        for f, pos, kind, text in project.divergences:
            if kind == "warned" or (f, pos, kind) in seen:
                continue     # warnings are printed above
            seen.add((f, pos, kind))
            print(f"{f}:{pos[0]}:{pos[1]}: note: {kind}: {text}", file=sys.stderr)
    if diags or (werror_portability and diags.warnings):
        for line in diags.format():
            print(line, file=sys.stderr)
        return 1
    from .cgen import Gen

    def generate():
        Gen(project, [f for f, _, _ in texts]).generate(outdir)
    return oneline.run("stc", generate, where=outdir)


if __name__ == "__main__":
    sys.exit(main())
