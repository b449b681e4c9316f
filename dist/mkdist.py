#!/usr/bin/env python3
"""Release archives of st_lib's two libraries, the protocol core and the chain's blocks.

The core (st_lib/core/) goes to build/dist/mip-logger-<version>.{tar.gz,zip}, the chain's
application blocks (st_lib/chain/, built on the core) to
build/dist/mip-logger-chain-<version>.{tar.gz,zip}.

    .venv/bin/python dist/mkdist.py --xsd build/docs/tc6_xml_v201.xsd -o build/dist
    .venv/bin/python dist/mkdist.py --version [chain]       # print a library's version (core)
    .venv/bin/python dist/mkdist.py --import-order [core|chain]  # a library's files in import
                                                            # order (default: core, then chain)
    .venv/bin/python dist/mkdist.py --reference docs        # docs/blocks.md, docs/blocks-chain.md

Each library's version has one source: the constants uMajor / uMinor / uPatch of its version
function (st_lib/core/MIP_Version.st, st_lib/chain/MIP_ChainVersion.st). Before anything is
written the script checks that CHANGELOG.md has an entry `## [<version>] - YYYY-MM-DD` for the
core and `## [chain <version>] - YYYY-MM-DD` for the chain library (CHANGELOG_HEADING), and that
LICENSE exists. Each library's import order has one source, st_lib/<library>/import-order.txt
(mipcosim.libraries); the script checks it against the files' dependencies (every file after
the ones it uses, the core using nothing of the chain) and refuses a wrong one in one line.
The core archive holds, under mip-logger-<version>/:

    st_lib/core/*.st                the sources, stored in import order (README.txt lists it)
    mip-logger-<version>.st         the same sources concatenated in import order (one import)
    mip-logger-<version>.xml        PLCopen XML (TC6 v2.01), validated against the schema
    scl/*.scl                       the blocks as TIA Portal SCL external sources, generated from
                                    st_lib by stc.scl_out, in import order (docs/wiring-s7.md)
    mip-logger-<version>.scl        the same SCL in one file, in import order (one import)
    blocks.md                       the block reference (docs/blocks.md, regenerated here)
    wireshark/mipmb.lua             the Wireshark dissector of MIP over Modbus (docs/wireshark.md)
    glue/<family>/*                 the vendor glue (dist/glue/: TwinCAT, CODESYS, S7), with its import steps
    mip-logger-<version>-<family>.xml  PLCopen XML of the library with the family's glue (twincat,
                                    codesys), validated against TC6 like the library's
    twincat/DUTs/*.TcDUT,           the library and the TwinCAT glue as the XML objects a TwinCAT 3 PLC
    twincat/POUs/*.TcPOU            project adds (Add > Existing Item...), one type or POU a file,
                                    generated from the .st files (twincat_objects); twincat/README.txt
    LICENSE, CHANGELOG.md, README.txt

The chain archive holds, under mip-logger-chain-<version>/, the chain library's own files in the
same form: st_lib/chain/*.st, mip-logger-chain-<version>.st / .xml / .scl, scl/*.scl, blocks.md
(docs/blocks-chain.md), LICENSE, CHANGELOG.md and README.txt (which names the core version it
needs: import the core first). No glue: the glue connects the core's blocks to a vendor's client.

The import orders are the ones of docs/blocks.md and docs/blocks-chain.md (every type and block
before its first use); `--import-order` prints them for build commands, and the pages that list
them are checked against them (tests/docs/test_docs_import_order.py).
The archives are reproducible: fixed member order and time stamps (SOURCE_DATE_EPOCH, or
2026-01-01). Every error is one line and a non-zero exit.
"""
from __future__ import annotations

import argparse
import gzip
import io
import os
import re
import sys
import tarfile
import tempfile
import time
import zipfile
from pathlib import Path

from mipdocs.blockref import render, uses_and_defines
from mipdocs.plcopen_export import export, validate
from mipdocs.stdecl import StError, parse_file
from stc import oneline

REPO = Path(__file__).resolve().parents[1]
WIRESHARK = "wireshark/mipmb.lua"     # dist/wireshark/mipmb.lua, at the same path in the archive
GLUE = "glue"                         # dist/glue/<family>/*, at the same paths in the archive

PRODUCT = "mip-logger"
LIBRARIES = ("core", "chain")         # mipcosim.libraries.LIBRARIES: the chain builds on the core
# per library: its archive's name, its version file and its CHANGELOG heading (our choice: the
# core keeps the heading of the single library's releases, the chain's names itself)
PRODUCTS = {"core": PRODUCT, "chain": f"{PRODUCT}-chain"}
VERSION_FILES = {"core": "st_lib/core/MIP_Version.st", "chain": "st_lib/chain/MIP_ChainVersion.st"}
VERSION_FILE = VERSION_FILES["core"]
CHANGELOG_HEADING = {"core": "## [{v}] - YYYY-MM-DD", "chain": "## [chain {v}] - YYYY-MM-DD"}
# releases made before the split, when both libraries were one: their heading is the core's
JOINT_RELEASES = ("0.1.0",)
REFERENCE = {"core": "blocks.md", "chain": "blocks-chain.md"}     # in docs/ and the archives
DEFAULT_EPOCH = 1767225600          # 2026-01-01T00:00:00Z
CONST = re.compile(r"^\s*u(Major|Minor|Patch)\s*:\s*UINT\s*:=\s*(\d+)\s*;", re.M)


class DistError(Exception):
    """One line for the user: FILE[:LINE]: error: MESSAGE."""


def read_version(repo: Path = REPO, lib: str = "core") -> str:
    vfile = VERSION_FILES[lib]
    path = repo / vfile
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DistError(f"{vfile}: error: {e.strerror}") from None
    parts = {}
    for m in CONST.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        if m.group(1) in parts:
            raise DistError(f"{vfile}:{line}: error: u{m.group(1)} is declared twice")
        parts[m.group(1)] = int(m.group(2))
    missing = [k for k in ("Major", "Minor", "Patch") if k not in parts]
    if missing:
        raise DistError(f"{vfile}: error: no constant u{missing[0]} : UINT := N; "
                        f"(the version is uMajor.uMinor.uPatch)")
    for k in ("Minor", "Patch"):
        if parts[k] > 99:
            raise DistError(f"{vfile}: error: u{k} = {parts[k]}: at most 99 (the version function "
                            f"returns MAJOR * 10000 + MINOR * 100 + PATCH)")
    return f"{parts['Major']}.{parts['Minor']}.{parts['Patch']}"


def check_changelog(version: str, repo: Path = REPO, lib: str = "core") -> None:
    path = repo / "CHANGELOG.md"
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DistError(f"CHANGELOG.md: error: {e.strerror}") from None
    if not re.search(r"^## \[Unreleased\]\s*$", text, re.M):
        raise DistError("CHANGELOG.md: error: no '## [Unreleased]' section (Keep a Changelog)")
    heads = [CHANGELOG_HEADING[lib].format(v=version)]
    if lib != "core" and version in JOINT_RELEASES:
        heads.append(CHANGELOG_HEADING["core"].format(v=version))
    pats = [re.escape(h).replace("YYYY\\-MM\\-DD", r"\d{4}-\d{2}-\d{2}") for h in heads]
    if not any(re.search(rf"^{p}\s*$", text, re.M) for p in pats):
        raise DistError(f"CHANGELOG.md: error: no entry '{heads[0]}' for the version in "
                        f"{VERSION_FILES[lib]}")
    if not (repo / "LICENSE").is_file():
        raise DistError("LICENSE: error: missing")


def _parse(repo: Path, files: list[str]):
    cwd = os.getcwd()
    os.chdir(repo)
    try:
        return [parse_file(f) for f in files]
    except StError as e:
        raise DistError(str(e)) from None
    finally:
        os.chdir(cwd)


def import_order(repo: Path = REPO, lib: str = "core"):
    """(the library's .st files relative to repo in the import order of its
    st_lib/<lib>/import-order.txt, their parsed units). Checked: the order file lists every .st
    file of the folder; each file uses no name of a file listed after it; the core uses no
    name of the chain library; the chain no name of a core file that does not exist."""
    from mipcosim.libraries import ORDER_FILE, LibraryError, library_files, order_entries
    root = repo / "st_lib"
    try:
        libs = LIBRARIES[:LIBRARIES.index(lib) + 1]
        files = {x: [f"st_lib/{f}" for f in library_files(x, root)] for x in libs}
        lines = {f"st_lib/{x}/{name}": n for x in libs for n, name in order_entries(root, x)}
    except (LibraryError, ValueError) as e:
        raise DistError(str(e) if isinstance(e, LibraryError)
                        else f"st_lib: error: no library {lib!r}") from None
    for x in libs:
        unlisted = sorted(set(str(p.relative_to(repo)) for p in (root / x).glob("*.st"))
                          - set(files[x]))
        if unlisted:
            raise DistError(f"st_lib/{x}/{ORDER_FILE}: error: {unlisted[0]} is not listed "
                            f"(every .st file of st_lib/{x}/ is, in import order)")
    # the dependencies, checked against the order of every library (a later library's names
    # are 'after' the whole earlier library: the core must use none of the chain's)
    every = [f for x in LIBRARIES for f in (files.get(x) or _listed(root, x))]
    units = _parse(repo, every)
    defines, uses = uses_and_defines(units)
    for i, f in enumerate(every):
        for g in every[i + 1:]:
            hit = sorted(uses[f] & defines[g])
            if hit:
                own = f.split("/")[1]
                where = f"st_lib/{own}/{ORDER_FILE}:{lines.get(f, 0)}" if own == g.split("/")[1] \
                    else f
                why = (f"the {own} library uses no name of the {g.split('/')[1]} library"
                       if own != g.split("/")[1] else f"list {Path(g).name} before it")
                raise DistError(f"{where}: error: {Path(f).name} uses {hit[0]} of {g}: {why}")
    by_file = {u.file: u for u in units}
    return files[lib], [by_file[f] for f in files[lib]]


def _listed(root: Path, lib: str) -> list[str]:
    """A later library's files (for the check that an earlier one uses none of them); its own
    order file is checked when it is built."""
    from mipcosim.libraries import LibraryError, library_files
    try:
        return [f"st_lib/{f}" for f in library_files(lib, root)]
    except LibraryError:
        return sorted(str(p.relative_to(root.parent)) for p in (root / lib).glob("*.st"))


def concatenated(order: list[str], version: str, repo: Path = REPO, product: str = PRODUCT) -> str:
    out = [f"(* {product} {version}: {Path(order[0]).parent} in one file, in import order.\n"
           f"   Generated by dist/mkdist.py from {', '.join(Path(f).name for f in order)}.\n"
           f"   Licence: see LICENSE in the release archive. *)\n"]
    for f in order:
        text = (repo / f).read_text(encoding="utf-8").rstrip("\n")
        out.append(f"\n(* ==== {Path(f).name} ==== *)\n{text}\n")
    return "".join(out)


def scl_sources(order: list[str], version: str, repo: Path = REPO,
                before: list[str] = ()) -> list[tuple[str, str]]:
    """[(scl/<name>.scl, text)] in import order: st_lib as TIA Portal SCL external sources,
    generated by stc.scl_out (one source of truth; a file without a block or a STRUCT type,
    such as a types file whose enumerations and array types the blocks carry themselves, has
    none). `before`: the files of the libraries it builds on (read for their types, not
    written)."""
    from stc.scl_out import SclError, generate_files
    try:
        out = generate_files([str(repo / f) for f in list(before) + list(order)], version)
    except SclError as e:
        raise DistError(str(e)) from None
    return [(f"scl/{Path(f).stem}.scl", out[str(repo / f)]) for f in order
            if str(repo / f) in out]


def scl_one_file(scl: list[tuple[str, str]], version: str, product: str = PRODUCT) -> str:
    out = [f"// {product} {version}: the library as TIA Portal SCL in one external source, in import\n"
           f"// order. Generated by dist/mkdist.py (stc.scl_out); licence: see LICENSE.\n"]
    # types first, then FCs / FBs (our choice: every type declared before any block that uses
    # it): the files with only types (STRUCTs, e.g. MIP_T_UnicosRequest) ahead, each group in
    # import order
    def types_only(text):
        return re.search(r'^(FUNCTION_BLOCK|FUNCTION|DATA_BLOCK) "', text, re.M) is None
    scl = [x for x in scl if types_only(x[1])] + [x for x in scl if not types_only(x[1])]
    for name, text in scl:
        out.append(f"\n// ==== {name} ====\n{text.rstrip(chr(10))}\n")
    return "".join(out)


def s7_import_order(scl_names: list[str], repo: Path = REPO) -> list[str]:
    """The TIA Portal import order of the archive's SCL: the library's blocks as scl_sources
    gives them (each after the ones it uses), then the S7 glue: MIP_S7ModbusIo before the
    blocks that hold it (the rest of glue/s7/*.scl by name)."""
    glue = sorted(p.name for p in (repo / "dist" / GLUE / "s7").glob("*.scl"))
    first = [n for n in glue if n == "MIP_S7ModbusIo.scl"]
    return list(scl_names) + [f"{GLUE}/s7/{n}" for n in first + [n for n in glue if n not in first]]


def glue_bytes(path: Path) -> bytes:
    """A glue file's bytes in the archive: the S7 .scl sources as TIA imports them
    (stc.scl_out.tia_bytes: a BOM when they hold non-ASCII), the others as they are."""
    from stc.scl_out import tia_bytes
    if path.suffix == ".scl":
        return tia_bytes(path.read_text(encoding="utf-8-sig"))
    return path.read_bytes()


def readme(order: list[str], version: str, scl_names: list[str] = ()) -> str:
    lines = [f"{PRODUCT} {version}: MIP chunked transfer blocks in IEC 61131-3 Structured Text",
             "(the protocol core library; the chain's application blocks, SIPROTEC relay reader",
             f"and server and the UNICOS hand-over, are the library {PRODUCTS['chain']}, built on",
             "this one)",
             "",
             f"Import either the single file {PRODUCT}-{version}.st, or the files of st_lib/core/",
             "in this order (each needs only the ones before it):", ""]
    lines += [f"  {i}. {f}" for i, f in enumerate(order, 1)]
    lines += ["",
              f"{PRODUCT}-{version}.xml is the same library as PLCopen XML (TC6 v2.01) for",
              "IDEs that import it (CODESYS, TwinCAT, Beremiz). blocks.md is the block",
              "reference. MIP_Version(0) returns the version as a number: "
              "MAJOR * 10000 + MINOR * 100 + PATCH.",
              "",
              f"{PRODUCT}-{version}.scl (or the files of scl/, same order) is the library as",
              "TIA Portal SCL external sources for S7-1200/1500: add it under External source",
              "files, then Generate blocks from source (docs/wiring-s7.md). Generated from",
              "st_lib; never compiled in TIA Portal by this project. TIA Portal import order",
              "of the separate .scl files (types, then the blocks each after the ones it uses,",
              "then the S7 glue; Generate blocks from source in this order):", ""]
    lines += [f"  {i}. {n}" for i, n in enumerate(s7_import_order(scl_names), 1)]
    lines += ["",
              f"{WIRESHARK} is a Wireshark dissector (Lua) that labels the MIP",
              "registers and counters in a capture of the PLC-modem link (Modbus/TCP).",
              "Install: copy it into Wireshark's personal Lua plugins folder,",
              "~/.local/lib/wireshark/plugins/ (`tshark -G folders` names it), and restart",
              "Wireshark; or load it for one run:",
              f"  tshark -X lua_script:{WIRESHARK} -r CAPTURE",
              "",
              f"{GLUE}/<family>/ holds the glue between the blocks and a vendor's Modbus client",
              "blocks (TwinCAT 3: Tc2_ModbusSrv; CODESYS V3: ModbusFB; S7: MB_CLIENT), to copy",
              "into the IDE; its README.md has the import steps.",
              ""]
    return "\n".join(lines)


CHAIN_README = """{top}: the chain's application blocks (SIPROTEC relay reader and server, UNICOS
hand-over to WinCC OA) in IEC 61131-3 Structured Text, built on the MIP core library

Needs the core library {core} {core_version} (its release archive
{core}-{core_version}): import the core first, then either the single file
{top}.st, or the files of st_lib/chain/ in this order (each needs only the
core and the ones before it):

{files}

{top}.xml is the same library as PLCopen XML (TC6 v2.01); it refers to the
core's types and blocks by name (import the core's XML first). blocks.md is the
block reference. MIP_ChainVersion(0) returns the version as a number:
MAJOR * 10000 + MINOR * 100 + PATCH.

{top}.scl (or the files of scl/, same order) is the library as TIA Portal SCL
external sources, imported after the core's {core}-{core_version}.scl
(generated from st_lib; never compiled in TIA Portal by this project). Import
order of the separate .scl files:

{scl}
"""


def readme_chain(order: list[str], version: str, core_version: str,
                 scl_names: list[str] = ()) -> str:
    """The chain archive's README.txt: the core version it needs, its import orders."""
    def numbered(items):
        return "\n".join(f"  {i}. {x}" for i, x in enumerate(items, 1))
    return CHAIN_README.format(top=f"{PRODUCTS['chain']}-{version}", core=PRODUCT,
                               core_version=core_version, files=numbered(order),
                               scl=numbered(scl_names))


def glue_files(repo: Path = REPO) -> list[str]:
    """The vendor glue files (dist/glue/<family>/*), as archive paths glue/<family>/NAME."""
    root = repo / "dist"
    return sorted(str(p.relative_to(root)) for p in (root / GLUE).glob("*/*") if p.is_file())


# ---- TwinCAT 3 XML objects (.TcDUT / .TcPOU): what a TwinCAT PLC project adds as a file
TC_HEAD = '<?xml version="1.0" encoding="utf-8"?>\n<TcPlcObject Version="1.1.0.1" ProductVersion="3.1.4024.12">\n'
_TC_MASK = re.compile(r"\(\*.*?\*\)|//[^\n]*|'[^']*'", re.S)
_TC_ITEM = re.compile(r"^(TYPE|FUNCTION_BLOCK|FUNCTION|PROGRAM)\b", re.M)
_TC_END = {"TYPE": "END_TYPE", "FUNCTION_BLOCK": "END_FUNCTION_BLOCK", "FUNCTION": "END_FUNCTION",
           "PROGRAM": "END_PROGRAM"}


def _tc_guid(name: str) -> str:
    """A fixed object id per name (the archive is reproducible)."""
    import uuid
    return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"mip-logger/twincat/{name}")) + "}"


def _tc_cdata(text: str, where: str) -> str:
    if "]]>" in text:
        raise DistError(f"{where}: error: ']]>' cannot go into a TwinCAT object's CDATA")
    return f"<![CDATA[{text}]]>"


def _tc_items(text: str, where: str):
    """[(kind, name, declaration, implementation)] of one ST file: every TYPE declaration as its
    own item (a DUT holds one type), every POU split after its last VAR section; the comment
    right before an item goes into its declaration."""
    masked = _TC_MASK.sub(lambda m: re.sub(r"[^\n]", " ", m.group()), text)
    out, prev_end = [], 0
    for m in _TC_ITEM.finditer(masked):
        if m.start() < prev_end:
            continue
        kind = m.group(1)
        end = re.compile(rf"^{_TC_END[kind]}\b[^\n]*\n?", re.M).search(masked, m.end())
        if not end:
            line = text.count("\n", 0, m.start()) + 1
            raise DistError(f"{where}:{line}: error: {kind} without {_TC_END[kind]}")
        gap = text[prev_end:m.start()]
        lead = gap[gap.rfind("(*"):] if gap.rstrip().endswith("*)") and "(*" in gap else ""
        lead = lead.lstrip("\n")
        prev_end = end.end()
        if kind == "TYPE":
            body, body_m = text[m.end():end.start()], masked[m.end():end.start()]
            depth, last = 0, 0
            for t in re.finditer(r"\bEND_STRUCT\b|\bSTRUCT\b|;", body_m, re.I):
                w = t.group().upper()
                depth += (w == "STRUCT") - (w == "END_STRUCT")
                if w == ";" and depth == 0:
                    decl = body[last:t.end()].strip("\n")
                    name = re.match(r"\s*(\w+)", body_m[last:t.end()]).group(1)
                    first = lead if not out or out[-1][0] != "TYPE" or last == 0 else ""
                    out.append(("TYPE", name, f"{first}TYPE\n{decl}\nEND_TYPE\n", None))
                    last = t.end()
            continue
        name = re.match(r"\w+\s+(\w+)", masked[m.start():]).group(1)
        pos = masked.index("\n", m.start()) + 1
        while True:
            nxt = re.compile(r"\s*(VAR\w*)\b").match(masked, pos)
            if not nxt:
                break
            ev = re.compile(r"^\s*END_VAR\b[^\n]*\n?", re.M).search(masked, nxt.end())
            if not ev:
                break
            pos = ev.end()
        out.append((kind, name, lead + text[m.start():pos], text[pos:end.start()].strip("\n") + "\n"))
    return out


def _tc_object(kind: str, name: str, decl: str, impl: str | None, where: str) -> str:
    ident = f'Name="{name}" Id="{_tc_guid(name)}"'
    if kind == "TYPE":
        return (TC_HEAD + f"  <DUT {ident}>\n    <Declaration>{_tc_cdata(decl, where)}</Declaration>\n"
                "  </DUT>\n</TcPlcObject>\n")
    return (TC_HEAD + f'  <POU {ident} SpecialFunc="None">\n'
            f"    <Declaration>{_tc_cdata(decl, where)}</Declaration>\n"
            f"    <Implementation>\n      <ST>{_tc_cdata(impl, where)}</ST>\n    </Implementation>\n"
            "  </POU>\n</TcPlcObject>\n")


TC_README = """The MIP blocks and the TwinCAT glue as TwinCAT 3 objects (docs/wiring-twincat.md, Import)

DUTs/*.TcDUT   one type a file (the library's types)
POUs/*.TcPOU   one function, function block or program a file: the library, then the glue
               MIP_TcModbusIo and the example programs MAIN_Outstation / MAIN_Central

In TwinCAT 3 XAE, in the PLC project: References > Add library > Tc2_ModbusSrv; then
right-click the folder DUTs > Add > Existing Item... and select every file of DUTs/, the same
with the folder POUs and every file of POUs/ (TwinCAT copies them into the project). Then set
the modem's IP address in the program you use and call it from the PLC task. Generated from
the .st files of this archive (glue/twincat/, st_lib/); never opened in TwinCAT by the project.
"""


def twincat_objects(order: list[str], repo: Path = REPO) -> list[tuple[str, str]]:
    """[(twincat/DUTs|POUs/<name>.TcDUT|.TcPOU, XML)]: st_lib in import order, then the TwinCAT
    glue files (dist/glue/twincat/*.twincat.st), and twincat/README.txt."""
    srcs = [repo / f for f in order] + sorted((repo / "dist" / GLUE / "twincat").glob("*.twincat.st"))
    out, seen = [], set()
    for path in srcs:
        where = os.path.relpath(path, repo)
        for kind, name, decl, impl in _tc_items(path.read_text(encoding="utf-8"), where):
            if name in seen:
                raise DistError(f"{where}: error: {name} is declared twice (one TwinCAT object a name)")
            seen.add(name)
            folder, ext = ("DUTs", "TcDUT") if kind == "TYPE" else ("POUs", "TcPOU")
            out.append((f"twincat/{folder}/{name}.{ext}", _tc_object(kind, name, decl, impl, where)))
    out.append(("twincat/README.txt", TC_README))
    return out


# ---- PLCopen XML of the library with a family's glue (CODESYS, TwinCAT import it)
PLCOPEN_GLUE = {"codesys": "*.codesys.st", "twincat": "*.twincat.st"}


def _iec_comments(text: str) -> str:
    """The text with each // comment written as (* ... *) (what the declaration reader takes;
    the POU bodies go into the XML as they are)."""
    out = []
    for line in text.split("\n"):
        quoted, cut = False, None
        for i, c in enumerate(line):
            if c == "'":
                quoted = not quoted
            elif not quoted and line.startswith("//", i):
                cut = i
                break
        if cut is not None:
            line = line[:cut] + "(*" + line[cut + 2:].replace("*)", "* )").replace("(*", "( *") + " *)"
        out.append(line)
    return "\n".join(out)


def plcopen_with_glue(units, order, version, xsd, repo: Path = REPO) -> list[tuple[str, str]]:
    """[(family, PLCopen XML)]: the library and the family's glue files (dist/glue/<family>/)
    in one TC6 project, each glue POU's body as in its file; validated when xsd is given."""
    out = []
    for fam, pattern in PLCOPEN_GLUE.items():
        files = sorted((repo / "dist" / GLUE / fam).glob(pattern))
        with tempfile.TemporaryDirectory() as tmp:
            glue_units = []
            # the glue block before the programs that use it
            for path in sorted(files, key=lambda p: not p.name.startswith("MIP_")):
                text = path.read_text(encoding="utf-8")
                where = os.path.relpath(path, repo)
                copy = Path(tmp) / path.name
                copy.write_text(_iec_comments(text), encoding="utf-8")
                try:
                    unit = parse_file(str(copy))
                except StError as e:
                    raise DistError(str(e).replace(str(copy), where)) from None
                bodies = {name: impl for kind, name, _d, impl in _tc_items(text, where) if impl}
                for pou in unit.pous:
                    pou.body = bodies[pou.name].rstrip("\n")
                unit.file = where
                for pou in unit.pous:
                    pou.file = where
                glue_units.append(unit)
            xml = export(list(units) + glue_units, f"{PRODUCT}-st_lib-{fam}", "2026-01-01T00:00:00",
                         order=list(order) + [u.file for u in glue_units], version=version)
            if xsd is not None:
                xml_path = Path(tmp) / f"{fam}.xml"
                xml_path.write_text(xml, encoding="utf-8")
                errors = validate(str(xsd), str(xml_path))
                if errors:
                    raise DistError(errors[0])
        out.append((fam, xml))
    return out


def _validated(xml: str, xsd: Path | None, name: str, repo: Path) -> str:
    if xsd is not None:
        if not xsd.is_file():
            raise DistError(f"{xsd}: error: schema missing (make {os.path.relpath(xsd, repo)})")
        with tempfile.TemporaryDirectory() as tmp:
            xml_path = Path(tmp) / f"{name}.xml"
            xml_path.write_text(xml, encoding="utf-8")
            errors = validate(str(xsd), str(xml_path))
        if errors:
            raise DistError(errors[0])
    return xml


REFERENCE_INTRO = {
    "core": ("The core library (`st_lib/core/`): the MIP protocol blocks. The chain's application "
             "blocks (`MIP_Soe*`, `MIP_Unicos*`) are a library of their own, built on this one: "
             "[blocks-chain.md](blocks-chain.md)."),
    "chain": ("The chain library (`st_lib/chain/`): the application blocks of the chain "
              "([chain.md](chain.md)), built on the core library ([blocks.md](blocks.md)): "
              "import the core's files first, then these."),
}


def reference(lib: str, repo: Path = REPO) -> str:
    """A library's block reference (docs/blocks.md for the core, docs/blocks-chain.md for the
    chain; blocks.md of its archive), in the library's import order."""
    order, units = import_order(repo, lib)
    cwd = os.getcwd()
    os.chdir(repo)
    try:
        return render(units, f"`st_lib/{lib}/*.st`", order=order,
                      title=f"Block reference: the {lib} library", intro=[REFERENCE_INTRO[lib]])
    finally:
        os.chdir(cwd)


def _write_archives(outdir: Path, top: str, members) -> list[Path]:
    epoch = int(os.environ.get("SOURCE_DATE_EPOCH", DEFAULT_EPOCH))
    tgz = outdir / f"{top}.tar.gz"
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for name, data in members:
            info = tarfile.TarInfo(name)
            info.size, info.mtime, info.mode = len(data), epoch, 0o644
            info.uname = info.gname = "root"
            tar.addfile(info, io.BytesIO(data))
    with open(tgz, "wb") as f, gzip.GzipFile(filename="", mode="wb", fileobj=f,
                                             mtime=epoch) as gz:
        gz.write(buf.getvalue())
    zpath = outdir / f"{top}.zip"
    stamp = time.gmtime(max(epoch, 315532800))[:6]
    with zipfile.ZipFile(zpath, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members:
            zi = zipfile.ZipInfo(name, stamp)
            zi.external_attr = 0o644 << 16
            zi.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(zi, data)
    return [tgz, zpath]


def core_members(xsd: Path | None, repo: Path = REPO):
    """(archive name, [(member, bytes)]) of the core library's release."""
    from stc.scl_out import tia_bytes
    version = read_version(repo)
    check_changelog(version, repo)
    order, units = import_order(repo, "core")
    top = f"{PRODUCT}-{version}"
    xml = _validated(export(units, f"{PRODUCT}-st_lib", "2026-01-01T00:00:00", order=order,
                            version=version), xsd, top, repo)
    scl = scl_sources(order, version, repo)
    members = [(f"{top}/README.txt", readme(order, version, [n for n, _ in scl]).encode()),
               (f"{top}/LICENSE", (repo / "LICENSE").read_bytes()),
               (f"{top}/CHANGELOG.md", (repo / "CHANGELOG.md").read_bytes())]
    members += [(f"{top}/{f}", (repo / f).read_bytes()) for f in order]
    members += [(f"{top}/{top}.st", concatenated(order, version, repo).encode()),
                (f"{top}/{top}.xml", xml.encode())]
    members += [(f"{top}/{name}", tia_bytes(text)) for name, text in scl]
    members += [(f"{top}/{top}.scl", tia_bytes(scl_one_file(scl, version))),
                (f"{top}/blocks.md", reference("core", repo).encode()),
                (f"{top}/{WIRESHARK}", (repo / "dist" / WIRESHARK).read_bytes())]
    members += [(f"{top}/{f}", glue_bytes(repo / "dist" / f)) for f in glue_files(repo)]
    members += [(f"{top}/{name}", text.encode()) for name, text in twincat_objects(order, repo)]
    members += [(f"{top}/{top}-{fam}.xml", text.encode())
                for fam, text in plcopen_with_glue(units, order, version, xsd, repo)]
    return top, members


def chain_members(xsd: Path | None, repo: Path = REPO):
    """(archive name, [(member, bytes)]) of the chain library's release: its own files only."""
    from stc.scl_out import tia_bytes
    product = PRODUCTS["chain"]
    version = read_version(repo, "chain")
    check_changelog(version, repo, "chain")
    core_order, _ = import_order(repo, "core")
    order, units = import_order(repo, "chain")
    top = f"{product}-{version}"
    xml = _validated(export(units, f"{product}-st_lib", "2026-01-01T00:00:00", order=order,
                            version=version), xsd, top, repo)
    scl = scl_sources(order, version, repo, before=core_order)
    members = [(f"{top}/README.txt", readme_chain(order, version, read_version(repo),
                                                  [n for n, _ in scl]).encode()),
               (f"{top}/LICENSE", (repo / "LICENSE").read_bytes()),
               (f"{top}/CHANGELOG.md", (repo / "CHANGELOG.md").read_bytes())]
    members += [(f"{top}/{f}", (repo / f).read_bytes()) for f in order]
    members += [(f"{top}/{top}.st", concatenated(order, version, repo, product).encode()),
                (f"{top}/{top}.xml", xml.encode())]
    members += [(f"{top}/{name}", tia_bytes(text)) for name, text in scl]
    members += [(f"{top}/{top}.scl", tia_bytes(scl_one_file(scl, version, product))),
                (f"{top}/blocks.md", reference("chain", repo).encode())]
    return top, members


def build(outdir: Path, xsd: Path | None, repo: Path = REPO) -> list[Path]:
    """Both libraries' archives; nothing is written unless both are complete."""
    releases = [core_members(xsd, repo), chain_members(xsd, repo)]
    outdir.mkdir(parents=True, exist_ok=True)
    return [p for top, members in releases for p in _write_archives(outdir, top, members)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="mkdist", description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--outdir", default=str(REPO / "build" / "dist"))
    ap.add_argument("--xsd", help="validate the PLCopen XML against this TC6 v2.01 schema")
    ap.add_argument("--version", nargs="?", const="core", choices=LIBRARIES,
                    help="print a library's version (default: the core's) and exit")
    ap.add_argument("--import-order", nargs="?", const="all", choices=LIBRARIES + ("all",),
                    help="print a library's files in import order, one a line (default: the "
                         "core's, then the chain's), and exit")
    ap.add_argument("--reference", metavar="DIR",
                    help="write each library's block reference (DIR/blocks.md: the core, "
                         "DIR/blocks-chain.md: the chain) and exit")
    ap.add_argument("--repo", default=str(REPO), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    repo = Path(a.repo).resolve()

    def step():
        if a.version:
            print(read_version(repo, a.version))
        elif a.import_order:
            libs = LIBRARIES if a.import_order == "all" else (a.import_order,)
            print("\n".join(f for lib in libs for f in import_order(repo, lib)[0]))
        elif a.reference:
            for lib in LIBRARIES:
                path = Path(a.reference) / REFERENCE[lib]
                try:
                    path.write_text(reference(lib, repo), encoding="utf-8")
                except OSError as e:
                    raise DistError(f"{path}: error: {e.strerror}") from None
        else:
            for p in build(Path(a.outdir), Path(a.xsd) if a.xsd else None, repo):
                print(f"dist: wrote {os.path.relpath(p)}")
    return oneline.run("mkdist", step, located=(DistError,))


if __name__ == "__main__":
    sys.exit(main())
