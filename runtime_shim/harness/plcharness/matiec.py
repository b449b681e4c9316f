"""The matiec flavour of a build: finding iec2c, translating with it, and reading what it
leaves (VARIABLES.csv: the symbol table; its RETAIN marks, or stc's RETAIN.c: the table of
retained variables in matiec's layout)."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

from .build_common import ELEMENTARY, BuildError, Symbol


def matiec_paths():
    """(iec2c, its lib directory): $IEC2C or iec2c on PATH, $MATIEC_LIB or lib beside the
    resolved iec2c; (None, None) without iec2c."""
    iec2c = os.environ.get("IEC2C") or shutil.which("iec2c")
    if not iec2c:
        return None, None
    lib = os.environ.get("MATIEC_LIB") or str(Path(iec2c).resolve().parent / "lib")
    return iec2c, lib


def matiec_available() -> bool:
    iec2c, lib = matiec_paths()
    return bool(iec2c) and Path(lib, "C", "iec_std_lib.h").is_file()


def _translate_matiec(sources, gen, workdir):
    iec2c, lib = matiec_paths()
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
    are computed when asked for. The table itself is the one stc writes (the paths here are
    upper case already)."""
    from stc.cgen.runtime_files import retain_table
    out = ["/* generated by plcharness.build: the program's RETAIN variables (matiec build) */",
           "#include <stddef.h>"]
    out += decls
    out += retain_table(retained)
    path.write_text("\n".join(out) + "\n")

