"""Build flow: ST files → translator (stc or matiec) → symbol table → shared library + executable.

    python -m plcharness.build -o OUTDIR [--compiler auto|stc|matiec] FILE.st...

leaves OUTDIR/libplc.so (for the harness, via ctypes), OUTDIR/plc (the real-mode executable),
OUTDIR/symbols.json (the variables, by IEC path) and OUTDIR/gen/ (the translator's output).

The steps it shares with the others are in build_common.py, the matiec flavour in matiec.py,
the cache in build_cache.py; their public names stay importable from here.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from stc.semantics import SEMANTICS as STC_SEMANTICS

from .config import is_mbconfig
from .build_cache import (_cache_root, _compiler_fingerprint, _core_objects, _hash_inputs,
                          _prune_cache)
from .build_common import (GCSE_LIMIT, RUNTIME_DIR, BuildError, BuildResult, Symbol, _cc, _compile,
                           _modbus_flags)
from .matiec import (_matiec_member_ref, _translate_matiec, _write_retain_c, matiec_retained,
                     read_variables_csv)
# public names of plcharness.build from before it was split: callers import them from here
from .build_common import ELEMENTARY, HERE, INSTALLED, REPO_ROOT  # noqa: F401
from .matiec import STANDARD_FB_INTERFACE, matiec_available, read_stc_retain  # noqa: F401


# ---------------------------------------------------------------- translators

def _stc_command():
    exe = Path(sys.executable).parent / "stc"
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("stc")
    if found:
        return [found]
    return [sys.executable, "-m", "stc.cli"]


def resolve_compiler(compiler: str) -> str:
    compiler = compiler.lower()
    if compiler == "auto":
        env = os.environ.get("PLCRT_COMPILER", "").lower()
        return env if env in ("stc", "matiec") else "stc"
    if compiler not in ("stc", "matiec"):
        raise BuildError(f"unknown compiler {compiler!r} (stc, matiec or auto)")
    return compiler



SEMANTICS = (None, *STC_SEMANTICS)   # None: stc's default (PLCRT_SEMANTICS, else matiec)


def is_openplc_config(path) -> bool:
    """True for an OpenPLC v3 mbconfig.cfg: the runtime's own test (config.is_mbconfig);
    False for a file that cannot be read."""
    try:
        return is_mbconfig(Path(path).read_text(errors="replace"))
    except OSError:
        return False


def _translate_stc(sources, gen, semantics=None):
    sem = [f"--semantics={semantics}"] if semantics else []
    cmd = _stc_command() + sem + ["-o", str(gen)] + [str(s) for s in sources]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True)
    except FileNotFoundError as e:
        raise BuildError(f"stc: cannot run {cmd[0]}: {e.strerror}") from None
    if proc.returncode != 0:
        # stc's own diagnostics are FILE:LINE:COL: error: ... lines: pass them on as they are
        msg = (proc.stderr.strip() + "\n" + proc.stdout.strip()).strip()
        raise BuildError(msg or f"stc failed with exit status {proc.returncode}")
    # its warnings (portability) stay with the build, cached or not, for whoever shows them
    # (the test kit does, once per build)
    warnings = [l for l in proc.stderr.splitlines() if ": warning: " in l]
    if warnings:
        (Path(gen) / "STC_WARNINGS.txt").write_text("\n".join(warnings) + "\n")



# ---------------------------------------------------------------- symbol tables

def read_symbols_tsv(path: Path):
    """SYMBOLS.tsv (stc): returns (symbols, decl lines)."""
    symbols, decls = [], []
    for n, raw in enumerate(path.read_text().splitlines(), 1):
        if raw.startswith("#decl"):
            decls.append(raw[len("#decl"):].lstrip("\t "))
            continue
        if not raw.strip() or raw.startswith("#") or raw.startswith("path\t"):
            continue
        cols = raw.split("\t")
        if len(cols) < 4:
            raise BuildError(f"{path}:{n}: error: expected 4 tab-separated columns")
        symbols.append(Symbol(cols[0].upper(), cols[1].upper(), cols[2].upper(), cols[3]))
    return symbols, decls



def matiec_arrays_via_stc(sources, workdir: Path, known, fb_paths, programs):
    """matiec's VARIABLES.csv has no arrays or structs. When stc translates the same sources,
    its SYMBOLS.tsv gives their paths and types (with the array bounds); the C lvalue follows
    matiec's layout: variables wrapped as {value, flags}, FB instances as plain structs,
    struct members plain, arrays as {table[...]}. Returns extra Symbols (may be empty)."""
    gen = workdir / "stc-types"
    try:
        _translate_stc(sources, gen)
        rows, _ = read_symbols_tsv(gen / "SYMBOLS.tsv")
    except (BuildError, OSError):
        return []
    extra = []
    for row in rows:
        if row.path in known or row.kind in ("LOCATED", "VAR_EXTERNAL", "VAR_IN_OUT"):
            continue
        ref = _matiec_member_ref(row.path, programs, fb_paths, whole=True)
        if ref is None:
            continue  # globals: matiec's C type name of an array global is not known here
        if "[" in row.type:
            dims = row.type.count(",") + 1
            ref += ".table" + "[0]" * dims
        extra.append(Symbol(row.path, row.type, row.kind, ref))
    return extra


def _programs_from_sources(sources):
    """PROGRAM inst WITH task : TYPE lines of the CONFIGURATION (stc's table has no such rows)."""
    progs = {}
    conf = res = None
    for src in sources:
        text = re.sub(r"\(\*.*?\*\)", " ", Path(src).read_text(), flags=re.S)
        for m in re.finditer(r"\b(CONFIGURATION|RESOURCE)\s+(\w+)|\bPROGRAM\s+(\w+)\s*"
                             r"(?:WITH\s+\w+\s*)?:\s*(\w+)", text, flags=re.I):
            if m.group(1):
                if m.group(1).upper() == "CONFIGURATION":
                    conf = m.group(2).upper()
                else:
                    res = m.group(2).upper()
            elif conf and res:
                progs[f"{conf}.{res}.{m.group(3).upper()}"] = m.group(4).upper()
    return progs


def _write_symbols_c(path: Path, symbols, decls):
    """plcrt_symbols.c: the variables' names and where each one is. The addresses are a table
    (a switch of one case per variable took gcc -O2 27 s for the 815,000 variables of a
    247-station central). A located variable's c_ref is `(*pointer)`, and the pointer is set
    when the program is loaded: its row holds the pointer's address, and a flag says to follow it."""
    out = ["/* generated by plcharness.build: addresses of the program's variables */",
           "#include <stddef.h>", "#include <string.h>"]
    out += decls
    out.append("const char *const plcrt_gen_symbol_names[] = {")
    out += [f'  "{s.path}",' for s in symbols]
    out.append("  0 };")
    out.append(f"const size_t plcrt_gen_n_symbols = {len(symbols)};")
    rows, follow = [], []
    for s in symbols:
        m = re.fullmatch(r"\(\*(.+)\)", s.c_ref)
        rows.append(f"  (void *)&({m.group(1) if m else s.c_ref}),")
        follow.append("1" if m else "0")
    out.append("static void *const plcrt_gen_addr_[] = {")
    out += rows
    out.append("  0 };")
    out.append("static const unsigned char plcrt_gen_follow_[] = {")
    out += [f"  {','.join(follow[i:i + 32])}," for i in range(0, len(follow), 32)]
    out.append("  0 };")
    out.append("void *plcrt_gen_symbol_addr(size_t i) {\n"
               "  void *p;\n"
               f"  if (i >= {len(symbols)}) return 0;\n"
               "  if (!plcrt_gen_follow_[i]) return plcrt_gen_addr_[i];\n"
               "  memcpy(&p, plcrt_gen_addr_[i], sizeof p); /* the located pointer's value */\n"
               "  return p;\n}")
    path.write_text("\n".join(out) + "\n")


# ---------------------------------------------------------------- C build

ABI_SYMBOLS = {"config_init__": "T", "config_run__": "T", "common_ticktime__": "D"}


def _check_abi(objs, compiler):
    """The program's objects must define the matiec ABI entry points (interfaces.md §1)."""
    try:
        proc = subprocess.run(["nm", "--defined-only", *map(str, objs)], capture_output=True,
                              text=True)
    except OSError:
        return  # no nm: the linker will complain instead
    if proc.returncode != 0:
        return
    defined = {line.split()[-1] for line in proc.stdout.splitlines() if len(line.split()) >= 3}
    missing = [name for name in ABI_SYMBOLS if name not in defined]
    if missing:
        raise BuildError(f"{compiler}: the program does not match the ABI: "
                         f"{', '.join(missing)} not defined (a CONFIGURATION with a RESOURCE, "
                         "a TASK and a PROGRAM instance is needed)")



def _check_outdir(outdir: Path):
    """outdir is replaced by the build: refuse anything that is not an earlier build's output
    (or an empty directory) rather than delete it; one line when it cannot be written."""
    if outdir.is_symlink():
        raise BuildError(f"{outdir}: error: is a symbolic link: give the directory it points to")
    if outdir.exists() and not outdir.is_dir():
        raise BuildError(f"{outdir}: error: exists and is not a directory")
    if outdir.is_dir():
        if any(outdir.iterdir()) and not ((outdir / "symbols.json").is_file() or (outdir / "gen").is_dir()):
            raise BuildError(f"{outdir}: error: not empty and not the output of plcrt-build: "
                             "not replaced")
        if not os.access(outdir.parent, os.W_OK):
            raise BuildError(f"{outdir}: error: cannot replace it (its directory is not writable)")
        return
    parent = outdir.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise BuildError(f"{outdir}: error: cannot create it: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise BuildError(f"{outdir}: error: cannot create it: {parent} is not writable")


def build_program(sources, outdir, compiler="auto", cflags=None, semantics=None) -> BuildResult:
    """Translate and link ST sources; the result lands in outdir (created).
    semantics: None (stc's default, matiec) or "matiec" / "openplc" / "iec" (stc --semantics:
    upstream matiec's values, those of OpenPLC v3's matiec fork, IEC 61131-3's; ignored when
    matiec itself translates)."""
    sources = [Path(s).resolve() for s in sources]
    for s in sources:
        if not s.exists():
            raise BuildError(f"{s}: error: no such file")
        if not s.is_file():
            raise BuildError(f"{s}: error: {'a directory' if s.is_dir() else 'not a regular file'}, "
                             "not an ST source")
    compiler = resolve_compiler(compiler)
    if semantics is None:
        # PLCRT_SEMANTICS=iec (or openplc) runs a whole test suite under those values (make
        # test does, for st_lib and the chain: an outcome that differs is a portability bug)
        semantics = os.environ.get("PLCRT_SEMANTICS") or None
    if semantics not in SEMANTICS:
        raise BuildError(f"semantics {semantics!r}: error: give matiec, openplc or iec")
    outdir = Path(outdir).resolve()
    _check_outdir(outdir)
    key = _hash_inputs(sources, compiler, _compiler_fingerprint(compiler) + repr(cflags) +
                       (f":semantics={semantics}" if semantics and compiler == "stc" else ""))
    cache = _cache_root()
    if cache and (cache / key / "symbols.json").is_file():
        try:
            os.utime(cache / key)  # recently used: pruned last
            if outdir.exists():
                shutil.rmtree(outdir)
            shutil.copytree(cache / key, outdir)
            return _load_result(outdir)
        except (OSError, shutil.Error, ValueError):
            pass  # pruned meanwhile by another process: build it again
    tmp = Path(tempfile.mkdtemp(prefix="plcrt-build-", dir=cache if cache else None))
    try:
        _build_into(sources, tmp, compiler, cflags or [], semantics, cache)
        if outdir.exists():
            shutil.rmtree(outdir)
        shutil.copytree(tmp, outdir)
        if cache:
            try:
                os.rename(tmp, cache / key)  # atomic; a concurrent build of the same key may win
                tmp = None
            except OSError:
                pass
            _prune_cache(cache)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return _load_result(outdir)


def _load_result(outdir: Path) -> BuildResult:
    meta = json.loads((outdir / "symbols.json").read_text())
    return BuildResult(outdir=outdir, library=outdir / "libplc.so", executable=outdir / "plc",
                       compiler=meta["compiler"],
                       symbols=[Symbol(**s) for s in meta["symbols"]],
                       programs=meta["programs"])


def _build_into(sources, out: Path, compiler: str, cflags, semantics=None, cache=None):
    gen = out / "gen"
    gen.mkdir(parents=True)
    include = [f"-I{gen}"]
    retained = []   # matiec: the table of RETAIN variables (stc writes its own RETAIN.c)
    if compiler == "stc":
        _translate_stc(sources, gen, semantics)
        if not (gen / "SYMBOLS.tsv").is_file():
            raise BuildError(f"stc: {gen}/SYMBOLS.tsv missing: the program does not match the ABI")
        symbols, decls = read_symbols_tsv(gen / "SYMBOLS.tsv")
        extra_symbols = []
        # the #decl lines name the program types of POUS.h
        if (gen / "POUS.h").is_file():
            decls.insert(0, '#include "POUS.h"')
        programs = _programs_from_sources(sources)
        if (gen / "SOURCES.txt").is_file():
            prog_c = [gen / l.strip() for l in (gen / "SOURCES.txt").read_text().splitlines()
                      if l.strip()]
        else:
            prog_c = [gen / "Config0.c"] + sorted(gen.glob("Res*.c"))
    else:
        lib = _translate_matiec(sources, gen, out)
        include.append(f"-I{Path(lib) / 'C'}")
        symbols, decls, programs, fb_paths, csv_retained = read_variables_csv(gen)
        extra_symbols = matiec_arrays_via_stc(sources, out, {s.path for s in symbols},
                                              fb_paths, programs)
        retained = matiec_retained(out / "stc-types", csv_retained, symbols, programs, fb_paths)
        prog_c = [gen / "Config0.c"] + sorted(gen.glob("Res*.c"))
    for f in prog_c + [gen / "LOCATED_VARIABLES.h"]:
        if not f.is_file():
            raise BuildError(f"{compiler}: {f.name} missing in the translator output: "
                             "the program does not match the ABI")
    cc = _cc()
    mb_cflags, mb_libs = _modbus_flags()
    core_inc = f"-I{RUNTIME_DIR / 'include'}"
    src = RUNTIME_DIR / "src"
    objs = []
    # -fno-semantic-interposition: libplc.so is linked -Bsymbolic, so a call between the
    # program's own functions never goes to another library anyway; the flag tells gcc so at
    # compile time, and it may then inline a small FUNCTION (st_lib's MIP_Internal_CheckStep,
    # MIP_Internal_StatusBit) into the block that calls it. Without it -fPIC makes every such call a
    # real one (bench_pair.st: 7165 instead of 5247 instructions per scan). gcc >= 5 and
    # clang accept it; it changes nothing in what iec2c or stc generate.
    base = ["-O2", "-fPIC", "-fno-semantic-interposition", "-g"] + cflags
    # program: generated code, warnings are the translator's business
    for c in prog_c:
        o = out / (c.stem + ".o")
        # gcc's global CSE is superlinear in a function's size: in the 800 KB of the
        # 247-station central (one program body calling 247 receivers) it took 28 of the 40 s
        # of the compile; a unit that large goes without it (normal programs are < 200 KB)
        big = ["-fno-gcse"] if c.stat().st_size > GCSE_LIMIT else []
        _compile([cc, "-std=gnu99", "-w", *base, *big, *include, "-c", str(c), "-o", str(o)],
                 f"compiling {c.name}")
        objs.append(o)
    _check_abi(objs, compiler)
    o = out / "plcrt_symbols.o"
    sym_cmd = [cc, "-std=gnu99", "-w", *base, *include, "-c", str(out / "plcrt_symbols.c"),
               "-o", str(o)]
    if extra_symbols:
        # the arrays and structs found through stc are a bonus: drop them if they do not fit
        _write_symbols_c(out / "plcrt_symbols.c", symbols + extra_symbols, decls)
        if subprocess.run(sym_cmd, capture_output=True).returncode == 0:
            symbols = symbols + extra_symbols
            extra_symbols = []
    if not o.is_file() or extra_symbols:
        _write_symbols_c(out / "plcrt_symbols.c", symbols, decls)
        _compile(sym_cmd, "compiling the symbol table (c_ref of SYMBOLS.tsv)")
    objs.append(o)
    if retained:
        o = out / "plcrt_retain_gen.o"
        ret_cmd = [cc, "-std=gnu99", "-w", *base, *include, "-c", str(out / "plcrt_retain_gen.c"),
                   "-o", str(o)]
        _write_retain_c(out / "plcrt_retain_gen.c", retained, decls)
        _compile(ret_cmd, "compiling the table of RETAIN variables")
        objs.append(o)
    o = out / "plcrt_abi.o"
    _compile([cc, "-std=gnu11", "-Wall", *base, core_inc, f"-I{gen}", "-c",
              str(src / "plcrt_abi.c"), "-o", str(o)], "compiling the located variables")
    objs.append(o)
    core_objs, main_o = _core_objects(cache, cc, ["-std=gnu11", "-Wall", *base, core_inc], mb_cflags,
                                     out)
    objs += core_objs
    libs = mb_libs + ["-lpthread", "-lm"]
    _compile([cc, "-shared", "-Wl,-Bsymbolic", "-o", str(out / "libplc.so"),
              *map(str, objs), *libs], "linking libplc.so")
    _compile([cc, "-o", str(out / "plc"), str(main_o), *map(str, objs), *libs],
             "linking the executable")
    for o in out.glob("*.o"):
        o.unlink()
    meta = {"compiler": compiler, "programs": programs,
            "symbols": [s.__dict__ for s in symbols]}
    (out / "symbols.json").write_text(json.dumps(meta, indent=1))


class _OneLineParser(argparse.ArgumentParser):
    """A bad command line is one line (argparse prints the usage too)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def main(argv=None):
    ap = _OneLineParser(prog="plcrt-build", description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--outdir", required=True)
    ap.add_argument("--compiler", default="auto", choices=["auto", "stc", "matiec"])
    ap.add_argument("--semantics", choices=STC_SEMANTICS, default=None,
                    help="stc only: run-time values of upstream matiec (stc's default), of "
                         "OpenPLC v3's matiec fork, or IEC 61131-3 (default: PLCRT_SEMANTICS)")
    ap.add_argument("sources", nargs="+")
    args = ap.parse_args(argv)
    try:
        res = build_program(args.sources, args.outdir, args.compiler, semantics=args.semantics)
    except BuildError as e:
        print(e, file=sys.stderr)  # already FILE:LINE:COL: error: ... or says what failed
        return 1
    except UnicodeDecodeError as e:
        print(f"plcrt-build: error: a source is not UTF-8 text ({e.reason} at byte {e.start})",
              file=sys.stderr)
        return 1
    except OSError as e:  # e.g. a file system that fails or fills up during the build
        where = f"{e.filename}: " if e.filename else ""
        print(f"plcrt-build: error: {where}{e.strerror or e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("plcrt-build: interrupted", file=sys.stderr)
        return 130
    print(f"{res.executable}\n{res.library}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
