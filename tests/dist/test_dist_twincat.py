"""`make dist`'s files for TwinCAT and CODESYS (issue 47): the PLCopen XML of the library with
each family's glue, valid against TC6 v2.01 (mkdist validates it); and the TwinCAT objects: twincat/DUTs/*.TcDUT and twincat/POUs/*.TcPOU in
the archive, one per type and POU of st_lib and of the TwinCAT glue, in TwinCAT's XML; blark
(the independent TwinCAT parser pinned in requirements.txt) parses every one with 0 errors, and
each object holds its source's text as it is (declaration + implementation = the .st POU)."""
import re
import subprocess
import sys
import tarfile
import xml.etree.ElementTree as ET
from pathlib import Path

import blark.parse as blark_parse
import pytest

REPO = Path(__file__).resolve().parents[2]
MKDIST = REPO / "dist" / "mkdist.py"
XSD = REPO / "build" / "docs" / "tc6_xml_v201.xsd"
NS = {"p": "http://www.plcopen.org/xml/tc6_0201"}


@pytest.fixture(scope="module")
def twincat(tmp_path_factory):
    assert XSD.exists(), f"{XSD.relative_to(REPO)} missing: run `make {XSD.relative_to(REPO)}`"
    out = tmp_path_factory.mktemp("dist-tc")
    r = subprocess.run([sys.executable, str(MKDIST), "--xsd", str(XSD), "-o", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (tgz,) = out.glob("mip-logger-[0-9]*.tar.gz")     # the core library's (the glue is the core's)
    with tarfile.open(tgz) as t:
        t.extractall(out / "x", filter="data")
    (top,) = (out / "x").iterdir()
    return top / "twincat"


def _names(pattern, files):
    return {m.group(1) for f in files for m in re.finditer(pattern, f.read_text(), re.M)}


def _blark_errors(files):
    errors, parts = [], 0
    for f in files:
        root = ET.parse(f).getroot()
        assert root.tag == "TcPlcObject"
        (obj,) = list(root)
        assert obj.tag == ("DUT" if f.suffix == ".TcDUT" else "POU") and obj.get("Name") == f.stem
        assert re.fullmatch(r"\{[0-9a-f-]{36}\}", obj.get("Id"))
        for r in blark_parse.parse(f):
            parts += 1
            if r.exception is not None:
                errors.append(f"{f.name}: {str(r.exception).strip().splitlines()[0]}")
    return errors, parts


def test_every_type_and_pou_is_an_object(twincat):
    duts = sorted((twincat / "DUTs").glob("*.TcDUT"))
    pous = sorted((twincat / "POUs").glob("*.TcPOU"))
    srcs = sorted((REPO / "st_lib" / "core").glob("*.st")) + sorted(
        (REPO / "dist" / "glue" / "twincat").glob("*.twincat.st"))
    want_pous = _names(r"^(?:FUNCTION_BLOCK|FUNCTION|PROGRAM)\s+(\w+)", srcs)
    assert {p.stem for p in pous} == want_pous
    assert {"MIP_TcModbusIo", "MAIN_Outstation", "MAIN_Central", "MIP_Sender"} <= want_pous
    assert {"MIP_T_Block", "MIP_T_ReadBlock", "E_MIP_Error"} <= {d.stem for d in duts}
    assert (twincat / "README.txt").read_text().count("Add > Existing Item") == 1


def test_blark_parses_the_glue_objects_and_their_types(twincat):
    """Quick tier: the glue's three POUs and the two array types it uses."""
    files = [twincat / "POUs" / f"{n}.TcPOU" for n in ("MIP_TcModbusIo", "MAIN_Outstation",
                                                       "MAIN_Central")]
    files += [twincat / "DUTs" / f"{n}.TcDUT" for n in ("MIP_T_Block", "MIP_T_ReadBlock")]
    errors, parts = _blark_errors(files)
    assert errors == [] and parts == 2 * 3 + 2


@pytest.mark.slow
def test_blark_parses_every_object(twincat):
    """Full tier: st_lib's objects too (blark takes minutes on them on a busy machine)."""
    files = sorted(twincat.rglob("*.TcDUT")) + sorted(twincat.rglob("*.TcPOU"))
    errors, parts = _blark_errors(files)
    assert errors == []
    assert parts >= len(files)


def test_the_glue_object_is_the_glue_file(twincat):
    """Declaration + implementation + END_FUNCTION_BLOCK = the shipped .st, so the object
    cannot drift from the file CI runs."""
    src = (REPO / "dist/glue/twincat/MIP_TcModbusIo.twincat.st").read_text()
    pou = ET.parse(twincat / "POUs" / "MIP_TcModbusIo.TcPOU").getroot().find("POU")
    decl = pou.find("Declaration").text
    impl = pou.find("Implementation/ST").text
    assert decl.startswith("(* MIP_TcModbusIo:") and decl.rstrip().endswith("END_VAR")
    assert (decl + "\n" + impl + "END_FUNCTION_BLOCK\n").replace("\n\n\n", "\n\n") == src


@pytest.mark.parametrize("family,pous", [
    ("codesys", ("MIP_CdsModbusIo", "PLC_Outstation", "PLC_Central")),
    ("twincat", ("MIP_TcModbusIo", "MAIN_Outstation", "MAIN_Central"))])
def test_plcopen_xml_with_the_glue(twincat, family, pous):
    """mkdist validated it against the TC6 schema (else no archive); here: the library's blocks
    and the family's glue POUs are in it, the glue's body as in its file."""
    (xml,) = twincat.parent.glob(f"*-{family}.xml")
    root = ET.parse(xml).getroot()
    names = {p.get("name") for p in root.iterfind(".//p:pou", NS)}
    assert {"MIP_Sender", "MIP_Receiver", *pous} <= names
    glue = next(p for p in root.iterfind(".//p:pou", NS) if p.get("name") == pous[0])
    body = "".join(glue.find("p:body/p:ST", NS).itertext()).strip()
    src = next((REPO / "dist" / "glue" / family).glob(f"{pous[0]}.*.st")).read_text()
    assert body and body in src
    types = {d.get("name") for d in root.iterfind(".//p:derived", NS)}
    assert any(t.endswith("ModbusFB.ClientTCP") or t.endswith("FB_MBReadRegs") for t in types)
