"""A user's program and its plcrt config: building it (stc or matiec) and checking that the config
maps only what the program declares."""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

from plcharness.build import BuildError, build_program
from plcharness.config import LOCATED as _LOCATED
from plcharness.config import ConfigError, duration_ns, read_file
from stc.semantics import SEMANTICS

from .base import KitError, _warn


def _read_config(path: Path):
    """The plcrt config as plcharness.config reads it; None for an OpenPLC mbconfig.cfg or a
    config plcrt refuses (it says what is wrong, file:line, when the PLC loads it)."""
    try:
        return read_file(path)
    except ConfigError:
        return None


def _retain_period(path: Path):
    """(line, value, ns) of a plcrt config's [retain] period, or None."""
    cfg = _read_config(path)
    retain = cfg.section("retain") if cfg else None
    if retain is None or "period" not in retain.keys:
        return None
    return retain.key_lines["period"], retain["period"], duration_ns(retain["period"])


def _mapped(config: Path) -> set:
    """Every located address a plcrt config maps (a range's whole image)."""
    out = set()
    for _, _, addr, count in _config_addresses(config):
        m = _LOCATED.fullmatch(addr)
        area, size, a = m.group(1).upper(), m.group(2).upper(), int(m.group(3))
        if size == "X" or count == 1:
            out.add(addr.upper())
        else:
            out.update(f"%{area}{size}{a + i}" for i in range(count))
    return out


def _config_addresses(path: Path):
    """(line number, key, address, count) of every located address a plcrt config maps:
    count > 1 for a range's image (its size), 1 for handshake bits and words."""
    cfg = _read_config(path)
    return [(line, key, addr, count) for _, key, line, addr, count in cfg.located()] if cfg else []


def _declared(build) -> set:
    """The located addresses the program declares (LOCATED_VARIABLES.h of the build)."""
    f = Path(build.outdir) / "gen" / "LOCATED_VARIABLES.h"
    out = set()
    if f.is_file():
        for m in re.finditer(r"__LOCATED_VAR\(\s*\w+\s*,\s*\w+\s*,\s*(\w)\s*,\s*(\w)\s*,\s*(\d+)"
                             r"(?:\s*,\s*(\d+))?", f.read_text()):
            out.add(f"%{m.group(1)}{m.group(2)}{m.group(3)}" + (f".{m.group(4)}" if m.group(4) else ""))
    return out


# diagnostics the runtime writes for whoever wants them (a device's error counter and online
# bit, a range's status word): a program may leave them undeclared
OPTIONAL_OUTPUTS = {"errors", "online", "status"}


def check_config(build, config: Path):
    """One line (KitError) for the first address the config maps that the program does not
    declare: handshake bits and words (trigger, done, error, length, the [retain] request and
    saved) must be declared, of a range's image at least one address; the diagnostics of
    OPTIONAL_OUTPUTS may stay undeclared."""
    declared = _declared(build)
    if not declared and config.suffix == ".cfg":
        return
    for line, key, addr, count in _config_addresses(config):
        if key in OPTIONAL_OUTPUTS:
            continue
        m = _LOCATED.fullmatch(addr)
        area, size, a = m.group(1), m.group(2), int(m.group(3))
        if count > 1 and size != "X":
            if not any(f"%{area}{size}{a + i}" in declared for i in range(count)):
                raise KitError(f"{config}:{line}: error: {key} = {addr} (size {count}): the program "
                               f"declares none of %{area}{size}{a}..%{area}{size}{a + count - 1}")
        elif addr not in declared:
            raise KitError(f"{config}:{line}: error: {key} = {addr}: the program does not declare {addr}")


def build(sources, workdir: Path, compiler="stc", tick_ms=None, semantics=None):
    """The user's ST sources built into a soft-PLC (one line per error: file:line:col).
    compiler: "stc" (the default), "matiec" or "auto" (matiec when iec2c is on PATH);
    semantics: stc's values where IEC 61131-3 leaves them open (None: PLCRT_SEMANTICS, else
    matiec's; "openplc": those of OpenPLC's matiec fork; "iec"). stc's warnings are shown
    once per build (KitWarning)."""
    import os
    from plcharness.build import matiec_available
    if compiler == "auto":
        compiler = "matiec" if matiec_available() else "stc"
    semantics = semantics or os.environ.get("PLCRT_SEMANTICS") or None
    if semantics is not None and semantics not in SEMANTICS:
        raise KitError(f"semantics {semantics!r}: use matiec, openplc or iec")
    srcs = [Path(s) for s in sources]
    for s in srcs:
        if not s.is_file():
            raise KitError(f"{s}: error: no such ST source")
    if srcs and not any(re.search(r"\bCONFIGURATION\b", re.sub(r"\(\*.*?\*\)", " ", s.read_text(
            errors="replace"), flags=re.S), re.I) for s in srcs):
        raise KitError(f"{srcs[-1]}: error: no CONFIGURATION: the kit runs a program from a "
                       "CONFIGURATION whose TASK has an INTERVAL (CONFIGURATION Config0 RESOURCE "
                       "Res0 ON PLC TASK tMain(INTERVAL := T#10ms, PRIORITY := 0); PROGRAM p WITH "
                       "tMain : YourProgram; ...), the last source")
    # the output directory is named by the sources' paths: another program (or the same names
    # elsewhere) gets its own, so a PLC restarted later reloads its own program
    digest = hashlib.sha1("\n".join(str(p.resolve()) for p in srcs).encode()).hexdigest()[:10]
    key = "-".join(p.stem for p in srcs[-2:])[:40] + "-" + digest + (f"-{semantics}" if semantics else "")
    try:
        result = build_program(srcs, Path(workdir) / f"build-{key}-{compiler}", compiler=compiler,
                               semantics=semantics)
        w = Path(result.outdir) / "gen" / "STC_WARNINGS.txt"
        if w.is_file():
            # a cached build's warnings name the sources it was built from: name these
            by_name = {p.name: os.path.normpath(p) for p in srcs}
            for line in w.read_text().splitlines():
                m = re.match(r"(.+?):(\d+:\d+: .*)", line)
                if m and Path(m.group(1)).name in by_name:
                    line = f"{by_name[Path(m.group(1)).name]}:{m.group(2)}"
                _warn(line)
        return result
    except BuildError as e:
        lines = [l for l in str(e).splitlines() if l.strip()]
        located = [l for l in lines if re.match(r".+:\d+:\d+: ", l)]
        first = next((l for l in located if ": error" in l), located[0] if located else
                     (lines[0] if lines else ""))
        raise KitError(first or f"{srcs[-1]}: error: the program does not build") from None


def _ranges(addrs):
    """['%MW0', '%MW1', '%MW3'] as '%MW0..%MW1, %MW3'."""
    out, run = [], []
    for a in addrs:
        if run and int(a[3:]) == int(run[-1][3:]) + 1:
            run.append(a)
            continue
        if run:
            out.append(run[0] if len(run) == 1 else f"{run[0]}..{run[-1]}")
        run = [a]
    if run:
        out.append(run[0] if len(run) == 1 else f"{run[0]}..{run[-1]}")
    return ", ".join(out)
