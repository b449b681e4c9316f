"""PLCopen XML (TC6 v2.01) export of st_lib: valid against the official schema, complete, and
carrying enough to rebuild the library (the ST rebuilt from the XML translates with stc)."""
import subprocess
from pathlib import Path

import pytest
from lxml import etree

from docs_helpers import REPO, ST_LIB, XSD, refused, rel, tool

NS = {"p": "http://www.plcopen.org/xml/tc6_0201", "x": "http://www.w3.org/1999/xhtml"}


@pytest.fixture(scope="module")
def xml(tmp_path_factory):
    assert XSD.exists(), (f"{XSD.relative_to(REPO)} missing: run `make "
                          f"{XSD.relative_to(REPO)}` (it downloads the plcopen source archive)")
    out = tmp_path_factory.mktemp("plcopen") / "st_lib.xml"
    r = tool("plcopen_export", "-o", out, *rel(ST_LIB))
    assert r.returncode == 0, r.stderr
    return out


def test_export_is_valid_tc6_v201(xml):
    r = tool("plcopen_export", "--validate", XSD, xml)
    assert r.returncode == 0, r.stderr


def test_the_validation_can_fail(xml, tmp_path):
    """A document the schema forbids (a POU without its pouType) is reported with its line."""
    bad = tmp_path / "bad.xml"
    bad.write_text(xml.read_text().replace(' pouType="functionBlock"', "", 1))
    r = refused("plcopen_export", "--validate", XSD, bad)
    assert f"{bad}:" in r.stderr and "pouType" in r.stderr


def test_export_is_deterministic(xml, tmp_path):
    again = tmp_path / "again.xml"
    assert tool("plcopen_export", "-o", again, *rel(ST_LIB)).returncode == 0
    assert again.read_bytes() == xml.read_bytes()


def test_every_block_type_and_variable_is_exported(xml):
    from mipdocs import stdecl
    root = etree.parse(str(xml)).getroot()
    pous = {p.get("name"): p for p in root.iterfind(".//p:pou", NS)}
    types = {t.get("name") for t in root.iterfind(".//p:dataType", NS)}
    for f in ST_LIB:
        u = stdecl.parse_file(f)
        for t in u.types:
            assert t.name in types
        for p in u.pous:
            assert p.name in pous, p.name
            names = [v.get("name") for v in pous[p.name].iterfind(".//p:variable", NS)]
            assert names == [v.name for s in p.sections for v in s.vars]


def test_every_interface_variable_is_documented(xml):
    """What an IDE shows when the integrator hovers over an input or output of a block (and
    every type and enum value): nothing is left without its documentation."""
    root = etree.parse(str(xml)).getroot()
    bare, count = [], 0
    for pou in root.iterfind(".//p:pou", NS):
        for tag in ("inputVars", "outputVars", "inOutVars"):
            for v in pou.iterfind(f"p:interface/p:{tag}/p:variable", NS):
                count += 1
                doc = v.find("p:documentation/x:p", NS)
                if doc is None or not (doc.text or "").strip():
                    bare.append(f"{pou.get('name')}.{v.get('name')}")
    for dt in root.iterfind(".//p:dataType", NS):
        doc = dt.find("p:documentation/x:p", NS)
        if doc is None or not (doc.text or "").strip():
            bare.append(dt.get("name"))
    assert count > 150, "found too few interface variables: fix the test"
    assert not bare, "no documentation: " + ", ".join(bare)


def xml_text(path):
    """Every text of the document (attributes' values aside), whitespace collapsed."""
    root = etree.parse(str(path)).getroot()
    return " ".join(" ".join(root.itertext()).split())


def test_every_comment_is_kept(xml):
    """No comment of the sources is lost on the way to an IDE: declarations' comments as the
    variables' documentation, group comments inside VAR blocks as their list's, doc headers as
    the POU's, file headers in the content header's Comment, enum values' in their type's,
    body comments in the body text."""
    from mipdocs import stdecl
    text = xml_text(xml)
    lost, count = [], 0
    for f in ST_LIB:
        for tok in stdecl.tokenize(Path(f).read_text(), f):
            if tok.kind != "comment":
                continue
            count += 1
            body = " ".join(tok.text[2:-2].split()).lstrip("@").strip()
            if body not in text:
                lost.append(f"{Path(f).name}:{tok.line}: {body[:60]}")
    assert count > 200, "found too few comments: fix the test"
    assert not lost, "comments missing from the XML:\n" + "\n".join(lost)


def test_group_comment_documents_its_group(xml):
    """MIP_Sender's "parameters sampled at the rising edge of xExecute" heads the uCfg...
    variables up to the blank line: exactly those form the list it documents."""
    root = etree.parse(str(xml)).getroot()
    pou = next(p for p in root.iterfind(".//p:pou", NS) if p.get("name") == "MIP_Sender")
    for vl in pou.iterfind("p:interface/p:localVars", NS):
        doc = vl.find("p:documentation/x:p", NS)
        if doc is not None and doc.text.startswith("parameters sampled"):
            names = [v.get("name") for v in vl.iterfind("p:variable", NS)]
            break
    else:
        raise AssertionError("no variable list carries the group comment")
    assert names == ["uCfgChunk", "xCfgBidi", "xCfgCentral", "xCfgPolled", "xCfgStatic",
                     "tCfgTimeout", "uCfgRetries", "xCfgRetained", "uCfgWindow"]


def test_file_header_is_the_content_comment(xml):
    root = etree.parse(str(xml)).getroot()
    c = root.find("p:contentHeader/p:Comment", NS)
    assert c is not None and c.text.startswith("file MIP_Types.st\nTypes shared by the MIP blocks")


def test_no_body_comment_names_another_pou():
    """Beremiz puts a POU before every other POU whose body text names it, comments included:
    a body comment naming another block reorders the library it regenerates from the XML, and
    plain iec2c then rejects it (issue 26). Bodies name other POUs only in code."""
    import re

    from mipdocs import stdecl
    units = [stdecl.parse_file(f) for f in ST_LIB]
    names = {p.name.upper() for u in units for p in u.pous}
    assert len(names) >= 10
    found = []
    for u in units:
        for p in u.pous:
            for m in re.finditer(r"\(\*.*?\*\)", p.body, re.S):
                for w in re.findall(r"[A-Za-z_]\w*", m.group()):
                    if w.upper() in names and w.upper() != p.name.upper():
                        found.append(f"{Path(u.file).name}: {p.name}'s body comment names {w}")
    assert not found, "\n".join(found)


def elementary_or_derived(t):
    child = t[0]
    tag = etree.QName(child).localname
    if tag == "derived":
        return child.get("name")
    if tag == "array":
        dims = ", ".join(f"{d.get('lower')}..{d.get('upper')}"
                         for d in child.iterfind("p:dimension", NS))
        return f"ARRAY[{dims}] OF {elementary_or_derived(child.find('p:baseType', NS))}"
    return tag


def value_text(v):
    s = v.find("p:simpleValue", NS)
    return s.get("value") if s is not None else None


def st_from_xml(path):
    """Rebuilds ST source from the XML (types, interfaces, bodies), as an importing IDE would."""
    root = etree.parse(str(path)).getroot()
    out = ["TYPE"]
    for dt in root.iterfind(".//p:dataType", NS):
        base = dt.find("p:baseType", NS)
        enum = base.find("p:enum", NS)
        struct = base.find("p:struct", NS)
        if enum is not None:
            vals = ", ".join(v.get("name") for v in enum.iterfind(".//p:value", NS))
            out.append(f"  {dt.get('name')} : ({vals});")
        elif struct is not None:
            out.append(f"  {dt.get('name')} : STRUCT")
            out += [f"    {v.get('name')} : {elementary_or_derived(v.find('p:type', NS))};"
                    for v in struct.iterfind("p:variable", NS)]
            out.append("  END_STRUCT;")
        else:
            out.append(f"  {dt.get('name')} : {elementary_or_derived(base)};")
    out.append("END_TYPE")
    kw = {"functionBlock": "FUNCTION_BLOCK", "program": "PROGRAM", "function": "FUNCTION"}
    sec = {"inputVars": "VAR_INPUT", "outputVars": "VAR_OUTPUT", "inOutVars": "VAR_IN_OUT",
           "localVars": "VAR", "tempVars": "VAR_TEMP"}
    for pou in root.iterfind(".//p:pou", NS):
        k = kw[pou.get("pouType")]
        ret = pou.find("p:interface/p:returnType", NS)
        ret = f" : {elementary_or_derived(ret)}" if ret is not None else ""
        out.append(f"{k} {pou.get('name')}{ret}")
        for vl in pou.find("p:interface", NS):
            if etree.QName(vl).localname == "returnType":
                continue
            const = " CONSTANT" if vl.get("constant") == "true" else ""
            out.append(sec[etree.QName(vl).localname] + const)
            for v in vl.iterfind("p:variable", NS):
                init = v.find("p:initialValue", NS)
                init = f" := {value_text(init)}" if init is not None else ""
                out.append(f"  {v.get('name')} : {elementary_or_derived(v.find('p:type', NS))}"
                           f"{init};")
            out.append("END_VAR")
        out.append(pou.find("p:body/p:ST/x:p", NS).text)
        out.append(f"END_{k}")
    return "\n".join(out) + "\n"


def test_st_rebuilt_from_the_xml_translates(xml, tmp_path):
    src = tmp_path / "from_xml.st"
    src.write_text(st_from_xml(xml))
    stc = Path(REPO / ".venv" / "bin" / "stc")
    r = subprocess.run([str(stc), "-o", str(tmp_path / "gen"), str(src)], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "gen" / "POUS.c").exists()


def test_bad_st_gives_one_line_and_no_xml(tmp_path):
    st = tmp_path / "bad.st"
    st.write_text("TYPE\n  T_X : ARRAY[0..3 OF WORD;\nEND_TYPE\n")
    r = refused("plcopen_export", "-o", tmp_path / "o.xml", st)
    assert r.stderr.strip() == f"{st}:2:20: error: expected ',' or ']', found 'OF'"
    assert not (tmp_path / "o.xml").exists()


def test_every_program_the_translator_accepts_exports_valid(tmp_path):
    """The ST reader is not a toy: each file of the translator's accept corpus (90 programs with
    types, FBs, functions, located variables, configurations) exports to schema-valid XML."""
    from mipdocs import plcopen_export
    from mipdocs import stdecl
    corpus = sorted((REPO / "tests" / "translator" / "accept").glob("*.st"))
    assert len(corpus) >= 50, "the translator's accept corpus moved"
    schema = etree.XMLSchema(etree.parse(str(XSD)))
    bad = []
    for f in corpus:
        try:
            xml = plcopen_export.export([stdecl.parse_file(str(f))], f.stem, "2026-01-01T00:00:00")
        except stdecl.StError as e:
            bad.append(str(e))
            continue
        doc = etree.fromstring(xml.encode())
        if not schema.validate(doc):
            bad.append(f"{f.name}: {schema.error_log.last_error}")
    assert not bad, "\n".join(bad)
