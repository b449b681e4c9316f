#!/usr/bin/env python3
"""Release archive of st_lib: build/dist/mip-logger-<version>.{tar.gz,zip}.

    .venv/bin/python dist/mkdist.py --xsd build/docs/tc6_xml_v201.xsd -o build/dist
    .venv/bin/python dist/mkdist.py --version        # print the version and exit
    .venv/bin/python dist/mkdist.py --import-order   # print st_lib/*.st in import order

The version has one source: the constants uMajor / uMinor / uPatch of st_lib/MIP_Version.st.
Before anything is written the script checks that CHANGELOG.md has an entry
`## [<version>] - YYYY-MM-DD` and that LICENSE exists. The archive holds, under
mip-logger-<version>/:

    st_lib/*.st                     the sources, stored in import order (README.txt lists it)
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

The import order is the one of docs/blocks.md (every type and block before its first use); it is
the only import order the project states: `--import-order` prints it for build commands, and the
pages that list it are checked against it (tests/docs/test_docs_import_order.py).
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

from mipdocs.blockref import dependency_order, render
from mipdocs.plcopen_export import export, validate
from mipdocs.stdecl import StError, parse_file
from stc import oneline

REPO = Path(__file__).resolve().parents[1]
WIRESHARK = "wireshark/mipmb.lua"     # dist/wireshark/mipmb.lua, at the same path in the archive
GLUE = "glue"                         # dist/glue/<family>/*, at the same paths in the archive

PRODUCT = "mip-logger"
VERSION_FILE = "st_lib/MIP_Version.st"
DEFAULT_EPOCH = 1767225600          # 2026-01-01T00:00:00Z
CONST = re.compile(r"^\s*u(Major|Minor|Patch)\s*:\s*UINT\s*:=\s*(\d+)\s*;", re.M)


class DistError(Exception):
    """One line for the user: FILE[:LINE]: error: MESSAGE."""


def read_version(repo: Path = REPO) -> str:
    path = repo / VERSION_FILE
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DistError(f"{VERSION_FILE}: error: {e.strerror}") from None
    parts = {}
    for m in CONST.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        if m.group(1) in parts:
            raise DistError(f"{VERSION_FILE}:{line}: error: u{m.group(1)} is declared twice")
        parts[m.group(1)] = int(m.group(2))
    missing = [k for k in ("Major", "Minor", "Patch") if k not in parts]
    if missing:
        raise DistError(f"{VERSION_FILE}: error: no constant u{missing[0]} : UINT := N; "
                        f"(the version is uMajor.uMinor.uPatch)")
    for k in ("Minor", "Patch"):
        if parts[k] > 99:
            raise DistError(f"{VERSION_FILE}: error: u{k} = {parts[k]}: at most 99 (MIP_Version(0) "
                            f"is MAJOR * 10000 + MINOR * 100 + PATCH)")
    return f"{parts['Major']}.{parts['Minor']}.{parts['Patch']}"


def check_changelog(version: str, repo: Path = REPO) -> None:
    path = repo / "CHANGELOG.md"
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DistError(f"CHANGELOG.md: error: {e.strerror}") from None
    if not re.search(r"^## \[Unreleased\]\s*$", text, re.M):
        raise DistError("CHANGELOG.md: error: no '## [Unreleased]' section (Keep a Changelog)")
    if not re.search(rf"^## \[{re.escape(version)}\] - \d{{4}}-\d{{2}}-\d{{2}}\s*$", text, re.M):
        raise DistError(f"CHANGELOG.md: error: no entry '## [{version}] - YYYY-MM-DD' for the "
                        f"version in {VERSION_FILE}")
    if not (repo / "LICENSE").is_file():
        raise DistError("LICENSE: error: missing")


def import_order(repo: Path = REPO):
    """(st_lib/*.st relative to repo in the import order of docs/blocks.md, parsed units)."""
    files = sorted(str(p.relative_to(repo)) for p in (repo / "st_lib").glob("*.st"))
    cwd = os.getcwd()
    os.chdir(repo)
    try:
        units = [parse_file(f) for f in files]
    except StError as e:
        raise DistError(str(e)) from None
    finally:
        os.chdir(cwd)
    return dependency_order(units), units


def concatenated(order: list[str], version: str, repo: Path = REPO) -> str:
    out = [f"(* {PRODUCT} {version}: st_lib in one file, in import order.\n"
           f"   Generated by dist/mkdist.py from {', '.join(Path(f).name for f in order)}.\n"
           f"   Licence: see LICENSE in the release archive. *)\n"]
    for f in order:
        text = (repo / f).read_text(encoding="utf-8").rstrip("\n")
        out.append(f"\n(* ==== {Path(f).name} ==== *)\n{text}\n")
    return "".join(out)


def scl_sources(order: list[str], version: str, repo: Path = REPO) -> list[tuple[str, str]]:
    """[(scl/<name>.scl, text)] in import order: st_lib as TIA Portal SCL external sources,
    generated by stc.scl_out (one source of truth; a file without a block or a STRUCT type,
    such as a types file whose enumerations and array types the blocks carry themselves, has
    none)."""
    from stc.scl_out import SclError, generate_files
    try:
        out = generate_files([str(repo / f) for f in order], version)
    except SclError as e:
        raise DistError(str(e)) from None
    return [(f"scl/{Path(f).stem}.scl", out[str(repo / f)]) for f in order
            if str(repo / f) in out]


def scl_one_file(scl: list[tuple[str, str]], version: str) -> str:
    out = [f"// {PRODUCT} {version}: st_lib as TIA Portal SCL in one external source, in import\n"
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
             "",
             f"Import either the single file {PRODUCT}-{version}.st, or the files of st_lib/",
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


def build(outdir: Path, xsd: Path | None, repo: Path = REPO) -> list[Path]:
    version = read_version(repo)
    check_changelog(version, repo)
    order, units = import_order(repo)
    top = f"{PRODUCT}-{version}"
    xml = export(units, f"{PRODUCT}-st_lib", "2026-01-01T00:00:00", order=order, version=version)
    if xsd is not None:
        if not xsd.is_file():
            raise DistError(f"{xsd}: error: schema missing (make {os.path.relpath(xsd, repo)})")
        with tempfile.TemporaryDirectory() as tmp:
            xml_path = Path(tmp) / f"{top}.xml"
            xml_path.write_text(xml, encoding="utf-8")
            errors = validate(str(xsd), str(xml_path))
        if errors:
            raise DistError(errors[0])
    outdir.mkdir(parents=True, exist_ok=True)
    cwd = os.getcwd()
    os.chdir(repo)
    try:
        blocks = render(units, "`st_lib/*.st`")
    finally:
        os.chdir(cwd)
    from stc.scl_out import tia_bytes
    scl = scl_sources(order, version, repo)
    members = [(f"{top}/README.txt", readme(order, version, [n for n, _ in scl]).encode()),
               (f"{top}/LICENSE", (repo / "LICENSE").read_bytes()),
               (f"{top}/CHANGELOG.md", (repo / "CHANGELOG.md").read_bytes())]
    members += [(f"{top}/{f}", (repo / f).read_bytes()) for f in order]
    members += [(f"{top}/{top}.st", concatenated(order, version, repo).encode()),
                (f"{top}/{top}.xml", xml.encode())]
    members += [(f"{top}/{name}", tia_bytes(text)) for name, text in scl]
    members += [(f"{top}/{top}.scl", tia_bytes(scl_one_file(scl, version))),
                (f"{top}/blocks.md", blocks.encode()),
                (f"{top}/{WIRESHARK}", (repo / "dist" / WIRESHARK).read_bytes())]
    members += [(f"{top}/{f}", glue_bytes(repo / "dist" / f)) for f in glue_files(repo)]
    members += [(f"{top}/{name}", text.encode()) for name, text in twincat_objects(order, repo)]
    members += [(f"{top}/{top}-{fam}.xml", text.encode())
                for fam, text in plcopen_with_glue(units, order, version, xsd, repo)]
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="mkdist", description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--outdir", default=str(REPO / "build" / "dist"))
    ap.add_argument("--xsd", help="validate the PLCopen XML against this TC6 v2.01 schema")
    ap.add_argument("--version", action="store_true", help="print the version and exit")
    ap.add_argument("--import-order", action="store_true",
                    help="print the st_lib files in import order, one a line, and exit")
    a = ap.parse_args(argv)

    def step():
        if a.version:
            print(read_version())
        elif a.import_order:
            print("\n".join(import_order()[0]))
        else:
            for p in build(Path(a.outdir), Path(a.xsd) if a.xsd else None):
                print(f"dist: wrote {os.path.relpath(p)}")
    return oneline.run("mkdist", step, located=(DistError,))


if __name__ == "__main__":
    sys.exit(main())
