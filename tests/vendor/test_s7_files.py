"""The .scl files of the release as TIA Portal imports them (issue 47, the import rules reported
from real imports): UTF-8 with a BOM when a file holds a non-ASCII character,
`{ S7_Optimized_Access := ... }` between the block's first line and VERSION, and the import
order written in the archive (README.txt's numbered list: each file after every block it uses,
types before blocks, the S7 glue after the library)."""
import re
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest
from stc.scl_out import generate_files, tia_bytes

REPO = Path(__file__).resolve().parents[2]
MKDIST = REPO / "dist" / "mkdist.py"
HEAD = re.compile(r'^(FUNCTION_BLOCK|FUNCTION|TYPE|DATA_BLOCK) "?([A-Za-z_]\w*)"?', re.M)
BOM = b"\xef\xbb\xbf"


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    out = tmp_path_factory.mktemp("s7dist")
    r = subprocess.run([sys.executable, str(MKDIST), "-o", str(out)], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    (tgz,) = out.glob("mip-logger-[0-9]*.tar.gz")     # the core library's (the glue is the core's)
    with tarfile.open(tgz) as t:
        return {m.name.split("/", 1)[1]: t.extractfile(m).read() for m in t.getmembers()
                if m.isfile()}


def test_non_ascii_gets_a_bom_and_stc_reads_it(tmp_path):
    st = tmp_path / "Umlaut.st"
    st.write_text("FUNCTION_BLOCK FB_Umlaut  (* Grüße: a comment TIA would garble *)\n"
                  "VAR_INPUT x : INT; END_VAR\nVAR_OUTPUT y : INT; END_VAR\ny := x + 1;\n"
                  "END_FUNCTION_BLOCK\n", encoding="utf-8")
    (text,) = generate_files([str(st)], "0.1.0").values()
    data = tia_bytes(text)
    assert data.startswith(BOM) and data[3:].decode("utf-8") == text
    assert not tia_bytes("FUNCTION x\n").startswith(BOM)      # ASCII stays as it is
    scl = tmp_path / "Umlaut.scl"
    scl.write_bytes(data)
    r = subprocess.run([str(REPO / ".venv" / "bin" / "stc"), "--dialect=scl", "-o",
                        str(tmp_path / "c"), str(scl)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def _scl_members(archive):
    return {n: d for n, d in archive.items() if n.endswith(".scl")}


def test_every_scl_file_bom_exactly_when_non_ascii(archive):
    scl = _scl_members(archive)
    assert len(scl) >= 20
    for name, data in scl.items():
        body = data[3:] if data.startswith(BOM) else data
        assert data.startswith(BOM) == (not body.isascii()), name


def test_the_attribute_stands_between_the_block_line_and_version(archive):
    n = 0
    for name, data in _scl_members(archive).items():
        lines = data.decode("utf-8-sig").split("\n")
        for i, line in enumerate(lines):
            m = HEAD.match(line)
            if not m:
                continue
            kind = m.group(1)
            if kind in ("FUNCTION_BLOCK", "FUNCTION", "DATA_BLOCK"):
                assert re.fullmatch(r"\{ S7_Optimized_Access := '(TRUE|FALSE)' \}", lines[i + 1]), \
                    (name, line, lines[i + 1])
                assert lines[i + 2].startswith("VERSION : "), (name, line)
                n += 1
            else:
                assert lines[i + 1].startswith("VERSION : "), (name, line)
    assert n >= 20


def _order(archive):
    readme = archive["README.txt"].decode()
    return re.findall(r"^ +\d+\. ((?:scl|glue/s7)/\S+\.scl)$", readme, re.M)


def test_the_import_order_is_written_and_each_file_follows_what_it_uses(archive):
    order = _order(archive)
    scl = _scl_members(archive)
    assert set(order) == {n for n in scl if "/" in n}, "every separate .scl file listed once"
    assert order.index("glue/s7/MIP_S7ModbusIo.scl") < order.index("glue/s7/MIP_S7Outstation.scl")
    defined = {}
    for pos, name in enumerate(order):
        text = scl[name].decode("utf-8-sig")
        for m in HEAD.finditer(text):
            defined[m.group(2)] = pos
    for pos, name in enumerate(order):
        text = re.sub(r"//.*|\(\*.*?\*\)", "", scl[name].decode("utf-8-sig"), flags=re.S)
        own = {m.group(2) for m in HEAD.finditer(text)}
        for used in set(re.findall(r'"(\w+)"', text)) - own:
            if used in defined:
                assert defined[used] < pos, f"{name} uses \"{used}\" imported later"
    # one file: the same blocks, types first, then FCs / FBs, then data blocks
    one = next(d for n, d in scl.items() if "/" not in n).decode("utf-8-sig")
    kinds = [m.group(1) for m in HEAD.finditer(one)]
    rank = {"TYPE": 0, "FUNCTION": 1, "FUNCTION_BLOCK": 1, "DATA_BLOCK": 2}
    assert [rank[k] for k in kinds] == sorted(rank[k] for k in kinds)
    for name in order:
        if name.startswith("scl/"):
            for m in HEAD.finditer(scl[name].decode("utf-8-sig")):
                assert f'"{m.group(2)}"' in one or f" {m.group(2)}\n" in one, m.group(2)
