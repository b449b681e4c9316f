"""st_lib's dialect and naming rules, the library through stc's include directories, and every
block carries the documentation header the docs generator reads. Each library compiling alone
with stc and matiec's iec2c: tests/st_lib/test_lib_split.py."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

from stlib_sim import LIB, LIB_FILES, LIB_PATHS

ALL_BLOCKS = ["MIP_Status", "MIP_Internal_WriteChannel", "MIP_Internal_Layout", "MIP_Internal_ReadDecoder", "MIP_Sender",
              "MIP_Receiver", "MIP_Link", "MIP_BufferSender", "MIP_SoeServer", "MIP_Internal_UnicosChannel",
              "MIP_UnicosEvents", "MIP_UnicosStatus", "MIP_Internal_SnapshotGate",
              "MIP_Internal_RecordBlock", "MIP_Internal_SenderWait", "MIP_Internal_Window",
              "MIP_Internal_SenderAck"]
# the two libraries compiled with stc and matiec, each alone (the core without the chain, the
# chain on the core): tests/st_lib/test_lib_split.py
USE_ALL = """
PROGRAM CompileCheck
VAR
  st : MIP_Status;
  snd : MIP_Sender;
  rcv : MIP_Receiver;
  link : MIP_Link;
  bsnd : MIP_BufferSender;
  buf : MIP_T_Buffer;
  srv : MIP_SoeServer;
  uni : MIP_UnicosEvents;
  sts : MIP_UnicosStatus;
END_VAR
st();
snd();
rcv();
link();
bsnd(aBuffer := buf);
srv();
uni();
sts();
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK tMain(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst0 WITH tMain : CompileCheck;
  END_RESOURCE
END_CONFIGURATION
"""


def test_library_through_stc_include_dir(tmp_path):
    """`stc -I st_lib/core -I st_lib/chain prog.st`: the libraries as include directories (any
    file order)."""
    prog = tmp_path / "prog.st"
    prog.write_text(USE_ALL)
    stc = Path(sys.executable).parent / "stc"
    cmd = [str(stc)] if stc.is_file() else [sys.executable, "-m", "stc.cli"]
    proc = subprocess.run(cmd + ["-o", str(tmp_path / "gen"), "-I", str(LIB / "core"),
                                 "-I", str(LIB / "chain"), str(prog)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


# ---------------------------------------------------------------- dialect and layout rules

def _code(text):
    """The text without (* comments *)."""
    return re.sub(r"\(\*.*?\*\)", " ", text, flags=re.S)


@pytest.mark.parametrize("name", LIB_FILES)
def test_dialect_rules(name):
    text = (LIB / name).read_text()
    code = _code(text)
    assert "//" not in code and "/*" not in code, "comments must be (* *)"
    assert not re.search(r"\b[A-Za-z_]\w*\.\d+\b", code), "no bit access w.0: use masks"
    for m in re.finditer(r"\bTYPE\b(.*?)\bEND_TYPE\b", code, flags=re.S):
        # a STRUCT's fields are not types
        types = re.sub(r"\bSTRUCT\b.*?\bEND_STRUCT\b", "STRUCT", m.group(1), flags=re.S)
        for tname in re.findall(r"^\s*(\w+)\s*:", types, flags=re.M):
            assert tname.startswith(("MIP_T_", "E_MIP_")), f"type {tname} needs the MIP prefix (-p)"
    assert not re.search(r"\(\s*\w+\s*:=\s*\d+", code), "no enum values with explicit numbers"
    pous = re.findall(r"^\s*(FUNCTION_BLOCK|FUNCTION|PROGRAM)\s+(\w+)", code, flags=re.M)
    assert len(pous) <= 1, f"one POU per file: {pous}"
    if pous:
        assert pous[0][1] + ".st" == Path(name).name


def _declared(code, sections=("VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT")):
    names = []
    for sec in sections:
        for m in re.finditer(rf"\b{sec}\b(.*?)\bEND_VAR\b", code, flags=re.S):
            names += re.findall(r"^\s*(\w+)\s*:", m.group(1), flags=re.M)
    return names


@pytest.mark.parametrize("block", ALL_BLOCKS)
def test_block_doc_header(block):
    """The header the docs generator reads: `(*@ block NAME`, then @purpose, @interface (a
    | table | with every input and output), @behaviour and @example sections."""
    (path,) = [LIB / f for f in LIB_FILES if Path(f).name == f"{block}.st"]
    text = path.read_text()
    m = re.match(r"\(\*@ block (\w+)\n(.*?)\*\)", text, flags=re.S)
    assert m and m.group(1) == block, "file must start with (*@ block NAME"
    header = m.group(2)
    sections = re.findall(r"^@(\w+)", header, flags=re.M)
    assert sections == ["purpose", "interface", "behaviour", "example"]
    table = header.split("@interface", 1)[1].split("@behaviour", 1)[0]
    documented = set()
    for row in re.findall(r"^\s*\|([^|]*)\|", table, flags=re.M):
        documented |= {n.strip() for n in row.split(",")}
    missing = [n for n in _declared(_code(text)) if n not in documented]
    assert not missing, f"not in the interface table of {block}: {missing}"


# the naming scheme of st_lib/README.md ("Naming"): type prefixes of variables, library
# prefixes of POUs, types and enumeration values
_TYPE_PREFIX = {"BOOL": "x", "UINT": "u", "INT": "i", "DINT": "di", "UDINT": "udi",
                "WORD": "w", "TIME": "t"}
_STD_FB = {"R_TRIG": "rt", "F_TRIG": "ft", "TON": "ton", "TOF": "tof", "TP": "tp"}


def _declarations():
    """(file, name, type) of every variable declared in st_lib/, comments removed."""
    out = []
    for p in LIB_PATHS:
        text = re.sub(r"\(\*.*?\*\)", "", Path(p).read_text(), flags=re.S)
        for block in re.findall(r"\bVAR(?:_INPUT|_OUTPUT|_IN_OUT|_GLOBAL)?\b(.*?)\bEND_VAR\b",
                                text, flags=re.S):
            for m in re.finditer(r"([A-Za-z_]\w*(?:\s*,\s*[A-Za-z_]\w*)*)\s*:\s*([A-Za-z_]\w*)",
                                 block):
                for name in (n.strip() for n in m.group(1).split(",")):
                    out.append((Path(p).name, name, m.group(2)))
    return out


def test_every_declaration_follows_the_naming_scheme():
    decls = _declarations()
    assert len(decls) > 100, "the declaration scan found too little: fix the test"
    structs = set(re.findall(r"^\s*(MIP_T_\w+)\s*:\s*STRUCT\b", "".join(
        Path(p).read_text() for p in LIB_PATHS), flags=re.M))
    bad = []
    for f, name, ty in decls:
        if name == "i" and ty in ("INT", "UINT"):
            continue                                    # loop counters
        want = _TYPE_PREFIX.get(ty) or _STD_FB.get(ty)
        if ty.startswith("E_MIP_"):
            want = "e"
        elif ty in structs:
            want = "st"
        elif ty.startswith("MIP_T_") or ty == "ARRAY":
            want = "a"
        elif ty.startswith("MIP_"):
            continue                                    # internal instances: named by role
        if want is None:
            bad.append(f"{f}: {name} : {ty} (a type the scheme does not name)")
        elif not re.fullmatch(re.escape(want) + r"[A-Z0-9]\w*", name):
            bad.append(f"{f}: {name} : {ty} (want the prefix {want!r})")
    assert not bad, "names outside st_lib/README.md's scheme:\n" + "\n".join(bad)


def test_every_pou_type_and_enum_value_carries_the_library_prefix():
    text = "".join(re.sub(r"\(\*.*?\*\)", "", Path(p).read_text(), flags=re.S)
                   for p in LIB_PATHS)
    pous = re.findall(r"^\s*(?:FUNCTION_BLOCK|FUNCTION)\s+(\w+)", text, flags=re.M)
    types = re.findall(r"^\s*(\w+)\s*:\s*(?:ARRAY|STRUCT|\()", text, flags=re.M)
    assert pous and types
    assert all(n.startswith("MIP_") for n in pous), pous
    assert all(n.startswith(("MIP_T_", "E_MIP_")) for n in types), types
    for body in re.findall(r"\bE_MIP_\w+\s*:\s*\((.*?)\)\s*;", text, flags=re.S):
        values = [v.strip() for v in body.split(",")]
        assert all(re.fullmatch(r"MIP_[A-Z]+_[A-Z0-9_]+", v) for v in values), values
