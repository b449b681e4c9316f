"""PLCopen XML (TC6 v2.01) export of ST sources: data types, POU interfaces, ST bodies.

    .venv/bin/python docs/tools/plcopen_export.py -o build/docs/st_lib-core.xml st_lib/core/*.st
    .venv/bin/python docs/tools/plcopen_export.py --validate XSD FILE.xml   # check a file

Types and POUs are written in an order in which every name is declared before it is used
(the import order of docs/blocks.md). Each POU body goes in as ST text; the doc header of a
block becomes its documentation; variable comments become variable documentation.
The output is deterministic: the creation date is fixed (--date, default
2026-01-01T00:00:00) so the same sources give the same bytes.
"""
from __future__ import annotations

import argparse
import re
import sys

from mipdocs.blockref import dependency_order
from mipdocs.stdecl import StError, TypeSpec, parse_file
from stc import oneline

NS = "http://www.plcopen.org/xml/tc6_0201"
XHTML = "http://www.w3.org/1999/xhtml"
SECTION_TAG = {"VAR_INPUT": "inputVars", "VAR_OUTPUT": "outputVars", "VAR_IN_OUT": "inOutVars",
               "VAR": "localVars", "VAR_TEMP": "tempVars", "VAR_EXTERNAL": "externalVars",
               "VAR_GLOBAL": "globalVars"}
POU_TYPE = {"FUNCTION_BLOCK": "functionBlock", "FUNCTION": "function", "PROGRAM": "program"}
TYPE_ALIASES = {"DATE_AND_TIME": "DT", "TIME_OF_DAY": "TOD"}


def esc(s):
    return (s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace('"', "&quot;"))


def type_xml(t: TypeSpec, ind):
    pad = " " * ind
    if t.kind == "elementary" and t.name in ("STRING", "WSTRING"):
        return f"{pad}<{t.name.lower()}/>\n"      # TC6: <string/>, not <STRING/>
    if t.kind == "elementary":
        return f"{pad}<{TYPE_ALIASES.get(t.name, t.name)}/>\n"
    if t.kind == "string":
        m = re.match(r"(W?STRING)\[(\d+)\]", t.name)
        tag = "wstring" if m.group(1) == "WSTRING" else "string"
        return f'{pad}<{tag} length="{m.group(2)}"/>\n'
    if t.kind == "derived":
        return f'{pad}<derived name="{esc(t.name)}"/>\n'
    if t.kind == "pointer":
        return f"{pad}<pointer>\n{pad}  <baseType>\n{type_xml(t.base, ind + 4)}{pad}  </baseType>\n{pad}</pointer>\n"
    out = f"{pad}<array>\n"
    for lo, hi in t.dims:
        out += f'{pad}  <dimension lower="{esc(lo)}" upper="{esc(hi)}"/>\n'
    out += f"{pad}  <baseType>\n{type_xml(t.base, ind + 4)}{pad}  </baseType>\n{pad}</array>\n"
    return out


def split_top(s, sep=","):
    parts, depth, cur = [], 0, ""
    for ch in s:
        if ch in "([":
            depth += 1
        elif ch in ")]":
            depth -= 1
        if ch == sep and depth == 0:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    if cur.strip():
        parts.append(cur.strip())
    return parts


def value_xml(init, ind):
    """Initial value: a simple value, an array [a, b, n(c)] or a struct (m := v, ...)."""
    pad = " " * ind
    init = " ".join(init.split())
    if init.startswith("[") and init.endswith("]"):
        out = f"{pad}<arrayValue>\n"
        for item in split_top(init[1:-1]):
            m = re.match(r"^(\d+)\s*\((.*)\)$", item)
            if m:
                out += (f'{pad}  <value repetitionValue="{m.group(1)}">\n'
                        f"{value_xml(m.group(2), ind + 4)}{pad}  </value>\n")
            else:
                out += f"{pad}  <value>\n{value_xml(item, ind + 4)}{pad}  </value>\n"
        return out + f"{pad}</arrayValue>\n"
    if init.startswith("(") and init.endswith(")") and ":=" in init:
        out = f"{pad}<structValue>\n"
        for item in split_top(init[1:-1]):
            member, _, val = item.partition(":=")
            out += (f'{pad}  <value member="{esc(member.strip())}">\n'
                    f"{value_xml(val.strip(), ind + 4)}{pad}  </value>\n")
        return out + f"{pad}</structValue>\n"
    return f'{pad}<simpleValue value="{esc(init)}"/>\n'


def doc_xml(text, ind):
    pad = " " * ind
    return (f"{pad}<documentation>\n{pad}  <xhtml:p><![CDATA[{cdata(text)}]]></xhtml:p>\n"
            f"{pad}</documentation>\n")


def cdata(text):
    return text.replace("]]>", "]]]]><![CDATA[>")


def var_xml(v, ind):
    pad = " " * ind
    addr = f' address="{esc(v.address)}"' if v.address else ""
    out = f'{pad}<variable name="{esc(v.name)}"{addr}>\n{pad}  <type>\n'
    out += type_xml(v.type, ind + 4) + f"{pad}  </type>\n"
    if v.init is not None:
        out += f"{pad}  <initialValue>\n{value_xml(v.init, ind + 4)}{pad}  </initialValue>\n"
    if v.comment:
        out += doc_xml(" ".join(v.comment.split()), ind + 2)
    return out + f"{pad}</variable>\n"


def export(units, name, date, order=None, version="1"):
    files = order or dependency_order(units)
    by_file = {u.file: u for u in units}
    o = ['<?xml version="1.0" encoding="utf-8"?>\n',
         f'<project xmlns="{NS}" xmlns:xhtml="{XHTML}">\n',
         f'  <fileHeader companyName="mip-logger project" productName="{esc(name)}" '
         f'productVersion="{esc(version)}" creationDateTime="{esc(date)}" '
         f'contentDescription="MIP logger transfer blocks, exported from ST sources by '
         f'docs/tools/plcopen_export.py"/>\n',
         f'  <contentHeader name="{esc(name)}">\n',
         *file_comments(units, files),
         "    <coordinateInfo>\n",
         '      <fbd>\n        <scaling x="1" y="1"/>\n      </fbd>\n',
         '      <ld>\n        <scaling x="1" y="1"/>\n      </ld>\n',
         '      <sfc>\n        <scaling x="1" y="1"/>\n      </sfc>\n',
         "    </coordinateInfo>\n", "  </contentHeader>\n", "  <types>\n", "    <dataTypes>\n"]
    for f in files:
        for t in by_file[f].types:
            o.append(f'      <dataType name="{esc(t.name)}">\n        <baseType>\n')
            if t.kind == "enum":
                o.append("          <enum>\n            <values>\n")
                for v, _ in t.values:
                    o.append(f'              <value name="{esc(v)}"/>\n')
                o.append("            </values>\n          </enum>\n")
            elif t.kind == "struct":
                o.append("          <struct>\n")
                for m in t.members:
                    o.append(var_xml(m, 12))
                o.append("          </struct>\n")
            else:
                o.append(type_xml(t.spec, 10))
            o.append("        </baseType>\n")
            if t.init is not None:
                o.append(f"        <initialValue>\n{value_xml(t.init, 10)}        </initialValue>\n")
            doc = t.comment or ""
            if t.kind == "enum":
                vals = [f"{v}: {' '.join(c.split())}" for v, c in t.values if c]
                doc = "\n".join([" ".join(doc.split())] + vals).strip()
            if doc:
                o.append(doc_xml(doc, 8))
            o.append("      </dataType>\n")
    o.append("    </dataTypes>\n    <pous>\n")
    for f in files:
        for p in by_file[f].pous:
            o.append(f'      <pou name="{esc(p.name)}" pouType="{POU_TYPE[p.kind]}">\n')
            o.append("        <interface>\n")
            if p.return_type is not None:
                o.append("          <returnType>\n" + type_xml(p.return_type, 12)
                         + "          </returnType>\n")
            for s in p.sections:
                tag = SECTION_TAG[s.kind]
                attrs = (' constant="true"' if s.constant else "") + (
                    ' retain="true"' if s.retain else "")
                for vars_, doc in var_lists(s):
                    o.append(f"          <{tag}{attrs}>\n")
                    for v in vars_:
                        o.append(var_xml(v, 12))
                    if doc:
                        o.append(doc_xml(doc, 12))
                    o.append(f"          </{tag}>\n")
            o.append("        </interface>\n")
            o.append("        <body>\n          <ST>\n")
            o.append(f"            <xhtml:p><![CDATA[{cdata(p.body)}]]></xhtml:p>\n")
            o.append("          </ST>\n        </body>\n")
            if p.doc:
                o.append(doc_xml(dedent_doc(p.doc), 8))
            o.append("      </pou>\n")
    o.append("    </pous>\n  </types>\n  <instances>\n    <configurations/>\n  </instances>\n")
    o.append("</project>\n")
    return "".join(o)


def var_lists(section):
    """A VAR block as one or more variable lists [(vars, documentation)]. A stand-alone
    comment inside the block (a group comment such as "parameters sampled at the rising edge
    ...") heads the declarations below it up to the next blank line, group comment or END_VAR:
    they become a list of their own whose documentation it is (TC6 gives a list one
    documentation), so the comment stays with what it describes. A comment before END_VAR
    documents the last list."""
    cuts = {}
    for idx, text in section.groups:
        cuts.setdefault(idx, []).append(" ".join(text.split()))
    ends = set(section.breaks)
    lists, cur, doc = [], [], []
    for i, v in enumerate(section.vars):
        if i in cuts or (doc and i in ends):
            if cur:
                lists.append((cur, "\n".join(doc)))
                cur, doc = [], []
            doc += cuts.get(i, [])
        cur.append(v)
    doc += cuts.get(len(section.vars), [])
    lists.append((cur, "\n".join(doc)))
    return lists


def file_comments(units, files):
    """The files' `(*@ file ... *)` headers as the content header's Comment (TC6 has no
    element per source file): one paragraph per file, in import order."""
    by_file = {u.file: u for u in units}
    texts = [dedent_doc(by_file[f].file_doc).strip() for f in files if by_file[f].file_doc]
    if not texts:
        return []
    return [f"    <Comment>{esc(chr(10).join(texts))}</Comment>\n"]


def dedent_doc(doc):
    lines = doc.strip("\n").split("\n")
    rest = [x for x in lines[1:] if x.strip()]
    cut = min((len(x) - len(x.lstrip()) for x in rest), default=0)
    return "\n".join([lines[0].strip()] + [x[cut:].rstrip() for x in lines[1:]]).strip() + "\n"


def validate(xsd_path, xml_path):
    """Returns a list of 'FILE:LINE: error: ...' messages (empty: valid)."""
    from lxml import etree
    try:
        schema = etree.XMLSchema(etree.parse(xsd_path))
    except (OSError, etree.XMLSchemaParseError, etree.XMLSyntaxError) as e:
        return [f"{xsd_path}: error: cannot load the schema: {e}"]
    try:
        doc = etree.parse(xml_path)
    except (OSError, etree.XMLSyntaxError) as e:
        return [f"{xml_path}: error: not well-formed XML: {e}"]
    if schema.validate(doc):
        return []
    return [f"{xml_path}:{err.line}: error: {err.message}" for err in schema.error_log]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="plcopen_export", description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", help="ST sources (or, with --validate, the XML file)")
    ap.add_argument("-o", "--output", help="the XML file to write")
    ap.add_argument("--name", default="st_lib", help="project name in the content header")
    ap.add_argument("--date", default="2026-01-01T00:00:00", help="creationDateTime")
    ap.add_argument("--validate", metavar="XSD", help="validate the XML file(s) against XSD")
    a = ap.parse_args(argv)
    if a.validate:
        if not a.files:
            print("plcopen_export: error: --validate needs the XML file", file=sys.stderr)
            return 2
        errors = []
        for f in a.files:
            errors += validate(a.validate, f)
        for e in errors:
            print(e, file=sys.stderr)
        return 1 if errors else 0
    if not a.files or not a.output:
        print("plcopen_export: error: give -o FILE and at least one .st file", file=sys.stderr)
        return 2
    try:
        units = [parse_file(f) for f in a.files]
    except StError as e:
        print(e, file=sys.stderr)
        return 1
    xml = export(units, a.name, a.date)
    return oneline.write_output("plcopen_export", a.output, xml, make_dir=True)


if __name__ == "__main__":
    sys.exit(main())
