"""Build flow: ST files → translator (stc or matiec) → symbol table → shared library + executable.

    python -m plcharness.build -o OUTDIR [--compiler auto|stc|matiec] FILE.st...

leaves OUTDIR/libplc.so (for the harness, via ctypes), OUTDIR/plc (the real-mode executable),
OUTDIR/symbols.json (the variables, by IEC path) and OUTDIR/gen/ (the translator's output).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNTIME_DIR = HERE.parent.parent  # runtime_shim/
REPO_ROOT = RUNTIME_DIR.parent
# Installed by the test kit (kit/, docs/test-kit.md): the runtime's C sources and headers ship
# inside the package, and there is no checkout around it.
INSTALLED = (HERE / "_runtime" / "src").is_dir()
if INSTALLED:
    RUNTIME_DIR = HERE / "_runtime"
    REPO_ROOT = None
CORE_SOURCES = ["plcrt_core.c", "plcrt_image.c", "plcrt_config.c", "plcrt_master.c", "plcrt_transport.c",
                "plcrt_serial_line.c", "plcrt_slave.c", "plcrt_retain.c"]
GCSE_LIMIT = 512 * 1024  # bytes of a generated C file compiled without -fgcse (see _build_into)
BUILD_FORMAT = "4"  # bump when the generated files change, to invalidate the cache

ELEMENTARY = {
    "BOOL", "BYTE", "SINT", "USINT", "WORD", "INT", "UINT", "DWORD", "DINT", "UDINT",
    "LWORD", "LINT", "ULINT", "REAL", "LREAL", "TIME", "DATE", "TOD", "DT",
    "TIME_OF_DAY", "DATE_AND_TIME", "STRING",
}


class BuildError(Exception):
    """A build step failed; str() is the compiler's message (file:line: error: ...)."""


@dataclass
class Symbol:
    path: str      # upper-case IEC path, CONFIG0.RES0.INSTANCE0.X
    type: str      # INT, WORD[0..147], ENUM:E_STATE, ...
    kind: str      # VAR, VAR_INPUT, ..., LOCATED
    c_ref: str     # C lvalue of the storage (first element for arrays)


@dataclass
class BuildResult:
    outdir: Path
    library: Path
    executable: Path
    compiler: str
    symbols: list[Symbol]
    programs: dict[str, str] = field(default_factory=dict)  # instance path → program type


# ---------------------------------------------------------------- translators

def _matiec_paths():
    iec2c = os.environ.get("IEC2C") or shutil.which("iec2c")
    if not iec2c:
        return None, None
    lib = os.environ.get("MATIEC_LIB") or str(Path(iec2c).resolve().parent / "lib")
    return iec2c, lib


def matiec_available() -> bool:
    iec2c, lib = _matiec_paths()
    return bool(iec2c) and Path(lib, "C", "iec_std_lib.h").is_file()


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


def _run(cmd, what, cwd=None):
    try:
        proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    except FileNotFoundError as e:
        raise BuildError(f"{what}: cannot run {cmd[0]}: {e.strerror}") from None
    if proc.returncode != 0:
        msg = (proc.stderr.strip() + "\n" + proc.stdout.strip()).strip()
        raise BuildError(f"{what} failed:\n{msg}")
    return proc


SEMANTICS = (None, *__import__("stc.semantics", fromlist=["SEMANTICS"]).SEMANTICS)  # None: stc's default


def is_openplc_config(path) -> bool:
    """True for an OpenPLC v3 mbconfig.cfg (no [sections]; its first key is Num_Devices or a
    deviceN. key), the same test the runtime's config loader makes."""
    try:
        text = Path(path).read_text(errors="replace")
    except OSError:
        return False
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        return bool(re.match(r"(Num_Devices|device\d+\.)", line))
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


def _translate_matiec(sources, gen, workdir):
    iec2c, lib = _matiec_paths()
    if not iec2c:
        raise BuildError("matiec: iec2c not found on PATH (or env IEC2C)")
    # iec2c takes one file: concatenate, and map error lines back to the originals.
    combined = workdir / "combined.st"
    line_map = []  # (first combined line, file, first line)
    text = []
    line = 1
    for src in sources:
        body = Path(src).read_text()
        if not body.endswith("\n"):
            body += "\n"
        line_map.append((line, str(src)))
        text.append(body)
        line += body.count("\n")
    combined.write_text("".join(text))
    flags = os.environ.get("MATIEC_FLAGS", "").split()  # e.g. OpenPLC's: -f -l -p -r -R -a
    proc = subprocess.run([iec2c, *flags, "-I", lib, "-T", str(gen), str(combined)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        def remap(m):
            n = int(m.group(1))
            start, name = max((s for s in line_map if s[0] <= n), key=lambda s: s[0])
            return f"{name}:{n - start + 1}:{m.group(2)}"
        out = (proc.stdout + proc.stderr)
        out = re.sub(re.escape(str(combined)) + r":(\d+)-(\d+)(?:\.\.\d+-\d+)?", remap, out)
        raise BuildError(out.strip() or f"iec2c failed with exit status {proc.returncode}")
    return lib


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


def _matiec_enums(gen: Path):
    names = set()
    for f in ("POUS.h",):
        p = gen / f
        if p.is_file():
            names.update(re.findall(r"__DECLARE_ENUMERATED_TYPE\(\s*(\w+)", p.read_text()))
    return names


def read_variables_csv(gen: Path):
    """Derive the SYMBOLS.tsv table from matiec's VARIABLES.csv (see docs/dev/interfaces.md §1).
    matiec lists elementary and enum variables (not arrays or structs)."""
    programs = {}
    rows = []
    section = None
    for raw in (gen / "VARIABLES.csv").read_text().splitlines():
        line = raw.strip()
        if line.startswith("//"):
            section = line[2:].strip().lower()
            continue
        if not line:
            continue
        cols = line.split(";")
        if section == "programs" and len(cols) >= 3:
            programs[cols[1].upper()] = cols[2].upper()
        elif section == "variables" and len(cols) >= 5:
            # the 7th column is matiec's RETAIN flag (1 for a variable of a RETAIN section,
            # or of an FB instance declared in one)
            rows.append((cols[1].upper(), cols[2].upper(), cols[4].upper(),
                         len(cols) >= 7 and cols[6].strip() == "1"))
    enums = _matiec_enums(gen)
    symbols = []
    decls = ['#include "iec_std_lib.h"', '#include "POUS.h"']
    declared = set()
    kind_names = {"VAR": "VAR", "IN": "LOCATED", "OUT": "LOCATED", "MEM": "LOCATED",
                  "EXT": "VAR_EXTERNAL"}
    for inst, ptype in programs.items():
        parts = inst.split(".")
        if len(parts) == 3:
            cname = f"{parts[1]}__{parts[2]}"
            decls.append(f"extern {ptype} {cname};")
            declared.add(cname)
    fb_paths = {path: typ for kind, path, typ, _ in rows if kind == "FB"}  # path -> FB type
    retained = []
    for kind, path, typ, retain in rows:
        if kind == "FB":
            continue
        if typ in ELEMENTARY and typ != "STRING":
            sym_type = {"TIME_OF_DAY": "TOD", "DATE_AND_TIME": "DT"}.get(typ, typ)
        elif typ in enums:
            sym_type = "ENUM:" + typ
        else:
            continue
        parts = path.split(".")
        inst = ".".join(parts[:3])
        pointer = kind in ("IN", "OUT", "MEM", "EXT")
        if inst in programs and len(parts) > 3:
            base = f"{parts[1]}__{parts[2]}"
            member = ".".join(parts[3:])
            lv = f"{base}.{member}.value"
        else:
            # a global of the configuration (CONFIG0.X) or of a resource (CONFIG0.RES0.X)
            base = "__".join(parts[-2:]) if len(parts) in (2, 3) else None
            if base is None:
                continue
            lv = f"{base}.value"
            if base not in declared:
                ctype = typ if typ in ELEMENTARY else typ
                suffix = "_p" if pointer else "_t"
                decls.append(f"extern __IEC_{ctype}{suffix} {base};")
                declared.add(base)
        c_ref = f"(*{lv})" if pointer else lv
        symbols.append(Symbol(path, sym_type, kind_names.get(kind, "VAR"), c_ref))
        if retain:
            retained.append((path, typ))
    return symbols, decls, programs, fb_paths, retained


def _matiec_member_ref(path, programs, fb_paths, whole=False):
    """The C lvalue of a variable of a program instance in matiec's layout, up to the value
    of the variable itself (X.value, S.value.member; arrays without .table), or None for a
    path outside the program instances. whole: also a path that ends at an FB instance (its
    plain struct)."""
    parts = path.split(".")
    inst = ".".join(parts[:3])
    if inst not in programs or len(parts) < 4:
        return None
    ref = f"{parts[1]}__{parts[2]}"
    prefix = inst
    wrapped = False
    for comp in parts[3:]:
        prefix = f"{prefix}.{comp}"
        if wrapped:
            ref += f".{comp}"           # a member of a STRUCT value
        elif prefix in fb_paths:
            ref += f".{comp}"           # an FB instance: a plain struct
        else:
            ref += f".{comp}.value"     # a variable: {value, flags}
            wrapped = True
    return ref if wrapped or whole else None


def read_stc_retain(gen: Path):
    """(path, type) of the retained variables in stc's RETAIN.c, in its order; None without
    the file (stc did not translate the sources)."""
    try:
        text = (gen / "RETAIN.c").read_text()
    except OSError:
        return None

    def table(name):
        m = re.search(r"\b" + name + r"\[\]\s*=\s*\{(.*?)\n\s*0\s*\};", text, flags=re.S)
        return re.findall(r'"((?:[^"\\]|\\.)*)"', m.group(1)) if m else []
    names, types = table("plcrt_gen_retain_names"), table("plcrt_gen_retain_types")
    if len(types) != len(names):
        types = [""] * len(names)
    return [(n.upper(), t) for n, t in zip(names, types)]


# The interface of IEC 61131-3's standard function blocks: what stc retains of an instance
# (not the internal state: the scan clock starts at 0 on every start, so a timer's start time
# from before a restart would hold it for the previous uptime; docs/retain.md)
STANDARD_FB_INTERFACE = {
    "SR": {"S1", "R", "Q1"}, "RS": {"S", "R1", "Q1"},
    "R_TRIG": {"CLK", "Q"}, "F_TRIG": {"CLK", "Q"},
    "CTU": {"CU", "R", "PV", "Q", "CV"}, "CTD": {"CD", "LD", "PV", "Q", "CV"},
    "CTUD": {"CU", "CD", "R", "LD", "PV", "QU", "QD", "CV"},
    "TP": {"IN", "PT", "Q", "ET"}, "TON": {"IN", "PT", "Q", "ET"}, "TOF": {"IN", "PT", "Q", "ET"},
}


def _standard_fb_type(name):
    """CTU_DINT, CTUD_ULINT, ... (matiec's typed counters) are CTU, CTUD, ..."""
    name = name.upper()
    return name if name in STANDARD_FB_INTERFACE else name.split("_")[0] \
        if name.split("_")[0] in ("CTU", "CTD", "CTUD") else None


def matiec_retained(stc_gen: Path, marked, symbols, programs, fb_types):
    """The RETAIN variables of a matiec build, as (path, type, C lvalue): the same ones as an
    stc build of the sources keeps (stc's RETAIN.c, which stc writes alongside the arrays and
    structs of matiec_arrays_via_stc), in matiec's layout. matiec marks retained variables
    (VARIABLES.csv's RETAIN column; its *_init__ sets __IEC_RETAIN_FLAG on the same ones) but
    cannot mark arrays, and marks the internal state of a standard FB (a TON's start time);
    when stc does not translate the sources, its marks are the table, without that state."""
    refs = {s.path: s.c_ref for s in symbols}
    stc_rows = read_stc_retain(stc_gen)
    out = []
    if stc_rows is not None:
        for path, typ in stc_rows:
            ref = refs.get(path) or _matiec_member_ref(path, programs, fb_types)
            if ref is not None:  # (array and struct globals: see matiec_arrays_via_stc)
                out.append((path, typ, ref))
        return out
    for path, typ in marked:
        owner, _, name = path.rpartition(".")
        std = _standard_fb_type(fb_types.get(owner, ""))
        if std and name not in STANDARD_FB_INTERFACE[std]:
            continue
        if path in refs:
            out.append((path, typ, refs[path]))
    return out


def _write_retain_c(path: Path, retained, decls):
    """plcrt_retain_gen.c: the table of retained variables that stc writes as RETAIN.c, for a
    matiec build (names, types, addresses and sizes; plcrt_retain.c saves and restores them).
    A located variable's lvalue is (*pointer), set when the program is loaded: the addresses
    are computed when asked for."""
    out = ["/* generated by plcharness.build: the program's RETAIN variables (matiec build) */",
           "#include <stddef.h>"]
    out += decls
    out.append("const char *const plcrt_gen_retain_names[] = {")
    out += [f'  "{p}",' for p, *_ in retained]
    out.append("  0 };")
    out.append("const char *const plcrt_gen_retain_types[] = {")
    out += [f'  "{t}",' for _, t, *_ in retained]
    out.append("  0 };")
    out.append(f"const size_t plcrt_gen_n_retain = {len(retained)};")
    out.append("void *plcrt_gen_retain_addr(size_t i) {\n  switch (i) {")
    out += [f"  case {i}: return (void *)&({lv});" for i, (_, _, lv) in enumerate(retained)]
    out.append("  default: return 0;\n  }\n}")
    out.append("size_t plcrt_gen_retain_size(size_t i) {\n  switch (i) {")
    out += [f"  case {i}: return sizeof({lv});" for i, (_, _, lv) in enumerate(retained)]
    out.append("  default: return 0;\n  }\n}")
    path.write_text("\n".join(out) + "\n")


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
        base, dims = row.type, 0
        if "[" in row.type:
            base = row.type[:row.type.index("[")]
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

def _cc():
    return os.environ.get("CC", "cc")


def _modbus_flags():
    """(cflags, libs) of libmodbus from pkg-config, with Debian's layout as the fallback."""
    try:
        cflags = subprocess.run(["pkg-config", "--cflags", "libmodbus"], capture_output=True,
                                text=True, check=True).stdout.split()
        libs = subprocess.run(["pkg-config", "--libs", "libmodbus"], capture_output=True,
                              text=True, check=True).stdout.split()
        return cflags, libs
    except (OSError, subprocess.CalledProcessError):
        return ["-I/usr/include/modbus"], ["-lmodbus"]


def _compile(cmd, what):
    _run(cmd, what)


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


def _hash_inputs(sources, compiler, extra):
    h = hashlib.sha256()
    h.update(BUILD_FORMAT.encode())
    h.update(compiler.encode())
    h.update(extra.encode())
    for src in sources:
        h.update(Path(src).name.encode())
        h.update(Path(src).read_bytes())
    for f in sorted((RUNTIME_DIR / "src").glob("*")) + sorted((RUNTIME_DIR / "include").glob("*")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()[:24]


def _compiler_fingerprint(compiler):
    if compiler == "matiec":
        iec2c, lib = _matiec_paths()
        if not iec2c:
            raise BuildError("matiec: iec2c not found on PATH (or env IEC2C)")
        st = os.stat(iec2c)
        # stc too: it supplies the arrays and structs of a matiec build
        return (f"{iec2c}:{st.st_size}:{st.st_mtime_ns}:{lib}:{os.environ.get('MATIEC_FLAGS', '')}"
                f":{_compiler_fingerprint('stc')}")
    # stc: its own sources decide what it produces
    h = hashlib.sha256()
    if REPO_ROOT is not None:
        stc_dir = REPO_ROOT / "translator" / "stc"
    else:
        import importlib.util
        spec = importlib.util.find_spec("stc")
        stc_dir = Path(spec.origin).parent if spec and spec.origin else Path("/nonexistent")
    for f in sorted(stc_dir.rglob("*")) if stc_dir.is_dir() else []:
        if f.is_file() and "__pycache__" not in f.parts:
            h.update(str(f.relative_to(stc_dir)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def _cache_root():
    env = os.environ.get("PLCRT_CACHE")
    if env == "off":
        return None
    if env:
        root = Path(env)
    elif REPO_ROOT is not None:
        root = REPO_ROOT / "build" / "runtime_shim" / "cache"
    else:   # installed: the user's cache directory
        root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "plcrt"
    try:
        root.mkdir(parents=True, exist_ok=True)
        return root
    except OSError:
        return None


CACHE_KEEP = 400  # entries (about 1 MB each); the oldest go first
CORE_DIR = "core-objects"  # in the cache: the runtime's own objects, see _core_objects
CORE_KEEP = 4              # sets of them (compiler and flags); the oldest go first


def _prune_cache(cache: Path, keep=CACHE_KEEP):
    """The entries of cache beyond the newest keep go (not CORE_DIR, not builds under way)."""
    try:
        entries = [e for e in cache.iterdir() if e.is_dir() and e.name != CORE_DIR
                   and not e.name.startswith("plcrt-build-")]
        if len(entries) <= keep:
            return
        entries.sort(key=lambda e: e.stat().st_mtime)
        for e in entries[:len(entries) - keep]:
            shutil.rmtree(e, ignore_errors=True)
    except OSError:
        pass  # another process pruned at the same time


def _core_objects(cache, cc, cflags, mb_cflags, out: Path):
    """The objects of the runtime's own sources (CORE_SOURCES and plcrt_main.c): the same for
    every program, so with a cache they are compiled once per compiler, flags and runtime
    sources instead of in every build (about 3 s of a small program's 6). Returns
    (the core objects, plcrt_main.o). Without a cache they are compiled into out."""
    names = CORE_SOURCES + ["plcrt_main.c"]
    src = RUNTIME_DIR / "src"

    def compile_into(d: Path):
        for name in names:
            flags = [*cflags, *mb_cflags] if name != "plcrt_main.c" else cflags
            _compile([cc, *flags, "-c", str(src / name), "-o", str(d / (Path(name).stem + ".o"))],
                     f"compiling {name}")

    def result(d: Path):
        objs = [d / (Path(n).stem + ".o") for n in names]
        return objs[:-1], objs[-1]

    if cache is None:
        compile_into(out)
        return result(out)
    h = hashlib.sha256()
    cc_path = shutil.which(cc)
    st = os.stat(cc_path) if cc_path else None
    h.update(f"{cc}:{cc_path}:{st.st_size if st else 0}:{st.st_mtime_ns if st else 0}".encode())
    h.update(repr(cflags).encode())
    h.update(repr(mb_cflags).encode())
    for f in sorted(src.glob("*")) + sorted((RUNTIME_DIR / "include").glob("*")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    root = cache / CORE_DIR
    d = root / h.hexdigest()[:24]
    core, main = result(d)
    if all(o.is_file() for o in core + [main]):
        try:
            os.utime(d)  # recently used: pruned last
        except OSError:
            pass
        return core, main
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix="plcrt-build-", dir=root))
    try:
        compile_into(tmp)
        try:
            os.rename(tmp, d)  # atomic; a concurrent build may have won: then use its objects
            tmp = None
        except OSError:
            pass
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    try:
        os.utime(d)  # this build's set stays, also when a concurrent build's rename won
    except OSError:
        pass
    _prune_cache(root, CORE_KEEP)
    return core, main


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
    # compile time, and it may then inline a small FUNCTION (st_lib's MIP_CheckStep,
    # MIP_StatusBit) into the block that calls it. Without it -fPIC makes every such call a
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
    o = out / "plcrt_glue.o"
    _compile([cc, "-std=gnu11", "-Wall", *base, core_inc, f"-I{gen}", "-c",
              str(src / "plcrt_glue.c"), "-o", str(o)], "compiling the located variables")
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
    ap.add_argument("--semantics", choices=["matiec", "openplc", "iec"], default=None,
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
