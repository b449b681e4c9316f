"""Value cross-check with the reference compiler: every accept-corpus program is also compiled
with matiec (iec2c + its lib/C), run for the same scans in the same virtual time, and must
produce the (* EXPECT ... *) values of the stc semantics that matches the flavour of the iec2c
found: --semantics=matiec for upstream matiec (beremiz), --semantics=openplc for the fork
OpenPLC v3 ships (told apart by a probe, or by IEC2C_FLAVOUR=matiec|openplc). Files marked
(* MATIEC-DIFFERS: reason *) are skipped with that reason for both flavours (stc deliberately
defines what matiec leaves undefined), (* UPSTREAM-DIFFERS: reason *) for upstream only,
(* OPENPLC-DIFFERS: reason *) for the fork only (its FOR up to the type's maximum never ends).
Skipped, with the reason, when iec2c is absent (as in CI)."""
import glob
import os
import re
import subprocess

import pytest
from stc.compiler import compile_files
from stc.diag import Diagnostics

import stc_harness as H

IEC2C, MATIEC_LIB = H.find_iec2c()
ACCEPT = sorted(glob.glob(os.path.join(H.HERE, "accept", "*.st")))

_PRINT = {"BOOL": ("%u", "unsigned"), "BYTE": ("%u", "unsigned"), "USINT": ("%u", "unsigned"),
          "SINT": ("%d", "int"), "WORD": ("%u", "unsigned"), "UINT": ("%u", "unsigned"),
          "INT": ("%d", "int"), "DWORD": ("%lu", "unsigned long"), "UDINT": ("%lu", "unsigned long"),
          "DINT": ("%ld", "long"), "LWORD": ("%llu", "unsigned long long"),
          "ULINT": ("%llu", "unsigned long long"), "LINT": ("%lld", "long long"),
          "REAL": ("%.6g", "double"), "LREAL": ("%.15g", "double")}


def _symbols(outdir):
    rows = {}
    with open(os.path.join(outdir, "SYMBOLS.tsv")) as f:
        for line in f:
            if line.startswith("#") or line.startswith("path\t"):
                continue
            path, typ, kind, ref = line.rstrip("\n").split("\t")
            rows[path] = typ
    return rows


def _full_path(rows, path):
    path = path.upper()
    if path in rows:
        return path
    hits = [k for k in rows if k.endswith("." + path)]
    assert len(hits) == 1, path
    return hits[0]


_SEG = re.compile(r"^([A-Z0-9_]+)(?:\[([-0-9,]+)\])?$")


def matiec_ref(project, full):
    """C expression (matiec layout) of the first element / the value at IEC path `full`."""
    cfg = project.config
    parts = full.split(".")
    assert parts[0] == cfg.name
    if parts[1] in cfg.globals:
        v = cfg.globals[parts[1]]
        return _walk(f"{cfg.name}__{v.name}", v, parts[2:], is_global=True)
    res = next(r for r in cfg.resources if r.name == parts[1])
    if parts[2] in res.globals:
        v = res.globals[parts[2]]
        return _walk(f"{res.name}__{v.name}", v, parts[3:], is_global=True)
    inst = next(i for i in res.instances if i.name == parts[2])
    base = f"{res.name}__{inst.name}"
    pou = inst.pou
    rest = parts[3:]
    while True:
        v = pou.vars[rest[0].split("[")[0]]
        if v.type.is_fb:
            base += "." + v.name
            pou = v.type.pou
            rest = rest[1:]
            continue
        return _walk(f"{base}.{v.name}", v, rest[1:], seg0=rest[0])


def _walk(base, v, rest, is_global=False, seg0=None):
    t = v.type
    indirect = v.location is not None or v.kind == "VAR_EXTERNAL"
    ref = f"(*{base}.value)" if indirect else f"{base}.value"
    m = _SEG.match(seg0) if seg0 else None
    segs = ([seg0] if seg0 else []) + rest
    first = True
    for s in segs:
        m = _SEG.match(s)
        name, idx = m.group(1), m.group(2)
        if not first:
            ref += "." + name
            t = t.fields[name][0]
        first = False
        if idx is not None:
            ks = [int(x) for x in idx.split(",")]
            ref += ".table" + "".join(f"[{k - lo}]" for k, (lo, _) in zip(ks, t.dims))
            t = t.elem
    if t.is_array:
        ref += ".table"
    return ref, t


def _main_c(project, rows, expects, sets, scans):
    out = ['#include <stdio.h>', '#include <stdlib.h>', '#include "iec_std_lib.h"', '#include "POUS.h"',
           "TIME __CURRENT_TIME;", "BOOL __DEBUG;",
           "#define __LOCATED_VAR(type, name, ...) type __##name; type *name = &__##name;"]
    out.append('#include "located_only.h"')
    out += ["#undef __LOCATED_VAR",
           "extern unsigned long long common_ticktime__;",
           "void config_init__(void);", "void config_run__(unsigned long tick);"]
    cfg = project.config
    for v in cfg.globals.values():
        out.append(f"extern __IEC_{v.type.name}_t {cfg.name}__{v.name};")
    for r in cfg.resources:
        for v in r.globals.values():
            out.append(f"extern __IEC_{v.type.name}_t {r.name}__{v.name};")
        for i in r.instances:
            out.append(f"extern {i.pou.name} {r.name}__{i.name};")
    out.append("int main(void) {")
    out.append("  long tick; long long now;")
    out.append("  config_init__();")
    for path, val in sets:
        ref, t = matiec_ref(project, _full_path(rows, path))
        out.append(f"  {ref} = {int(val)};")
    out.append(f"  for (tick = 0; tick < {scans}; tick++) {{")
    out.append("    config_run__((unsigned long)tick);")
    out.append("    now = (long long)__CURRENT_TIME.tv_sec * 1000000000LL + __CURRENT_TIME.tv_nsec + (long long)common_ticktime__;")
    out.append("    __CURRENT_TIME.tv_sec = (long)(now / 1000000000LL); __CURRENT_TIME.tv_nsec = (long)(now % 1000000000LL);")
    out.append("  }")
    for path, _ in expects:
        full = _full_path(rows, path)
        ref, t = matiec_ref(project, full)
        typ = rows[full]
        n = 1
        if "[" in typ:
            for lo, hi in re.findall(r"(-?\d+)\.\.(-?\d+)", typ):
                n *= int(hi) - int(lo) + 1
        out.append(f'  printf("%s=", "{path.upper()}");')
        elem = typ.split("[")[0]
        if n > 1 or "[" in typ:
            out.append('  printf("[");')
        for k in range(n):
            if "[" in typ:
                item = f"((&{ref}[0]" + "[0]" * (typ.count(",")) + f"))[{k}]" if False else \
                    f"(({_ctype(elem, t)} *)&{ref})[{k}]"
            else:
                item = ref
            if k:
                out.append('  printf(",");')
            if elem == "TIME":
                out.append(f"  printf(\"%lld\", (long long){item}.tv_sec * 1000000000LL + {item}.tv_nsec);")
            elif elem.startswith("ENUM:"):
                out.append(f'  printf("%d", (int){item});')
            else:
                fmt, cast = _PRINT[elem]
                out.append(f'  printf("{fmt}", ({cast}){item});')
        if n > 1 or "[" in typ:
            out.append('  printf("]");')
        out.append('  printf("\\n");')
    out.append("  return 0;\n}")
    return "\n".join(out) + "\n"


def _ctype(elem, t):
    if elem.startswith("ENUM:"):
        return elem[5:]
    return elem


@pytest.mark.skipif(not (IEC2C and MATIEC_LIB),
                    reason="iec2c not found (set IEC2C or put iec2c on PATH, and MATIEC_LIB) - "
                           "matiec value cross-check skipped")
@pytest.mark.parametrize("path", ACCEPT, ids=lambda p: os.path.splitext(os.path.basename(p))[0])
def test_matiec_same_values(path, tmp_path):
    with open(path) as f:
        text = f.read()
    flavour = H.iec2c_flavour(IEC2C, MATIEC_LIB, tmp_path)
    marks = {"matiec": ("MATIEC", "UPSTREAM"), "openplc": ("MATIEC", "OPENPLC")}[flavour]
    for mark in marks:
        m = re.search(r"\(\*\s*" + mark + r"-DIFFERS:\s*(.*?)\*\)", text, re.S)
        if m:
            pytest.skip(f"{flavour} differs: " + " ".join(m.group(1).split()))
    scans, expects, sets = H.expectations(text, flavour)
    d = Diagnostics()
    project = compile_files([(path, text, False)], d)
    assert not d, d.format()
    stc_out = tmp_path / "stc"
    r = H.run_stc([f"--semantics={flavour}", "-o", str(stc_out), path])
    assert r.returncode == 0, r.stderr
    rows = _symbols(str(stc_out))
    mdir = tmp_path / "matiec"
    mdir.mkdir()
    r = subprocess.run([IEC2C, "-I", MATIEC_LIB, "-T", str(mdir), path], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    # matiec also writes the names of VAR_EXTERNALs into LOCATED_VARIABLES.h: keep the macros
    with open(mdir / "LOCATED_VARIABLES.h") as f:
        located = [ln for ln in f.read().splitlines() if ln.startswith("__LOCATED_VAR(")]
    (mdir / "located_only.h").write_text("\n".join(located) + "\n")
    (mdir / "main.c").write_text(_main_c(project, rows, expects, sets, scans))
    exe = tmp_path / "mprog"
    p = subprocess.run(["cc", "-w", "-I", str(mdir), "-I", os.path.join(MATIEC_LIB, "C"), "-o", str(exe),
                        *sorted(str(mdir / f) for f in os.listdir(str(mdir))
                                if f.endswith(".c") and f != "POUS.c"), "-lm"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    got = dict(line.split("=", 1) for line in run.stdout.splitlines())
    for sym, want in expects:
        assert got[sym.upper()] == want.replace(" ", ""), \
            f"{sym}: {flavour} gives {got[sym.upper()]}, stc --semantics={flavour} {want}"
