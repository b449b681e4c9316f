"""st_lib is two libraries (issue 46, st_lib/README.md): the core (st_lib/core/) compiles alone,
without any file of the chain library, and names none of the chain's types or blocks; the chain
library (st_lib/chain/) compiles on top of the core. With stc always, with matiec's iec2c (plain
flags and OpenPLC's) where it is installed. Each library's files are the ones its
import-order.txt lists, in that order (mipcosim.libraries, the one source)."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from mipcosim.libraries import LibraryError, library_files
from mipdocs import stdecl
from plcharness.matiec import matiec_paths

REPO = Path(__file__).resolve().parents[2]
LIB = REPO / "st_lib"
CORE = [LIB / f for f in library_files("core", LIB)]
CHAIN = [LIB / f for f in library_files("chain", LIB)]
OPENPLC_FLAGS = ["-f", "-l", "-p", "-r", "-R", "-a"]


def _program(blocks):
    """A program with one instance of each block [(name, [(in-out, type)])], each called (its
    in-outs given a variable), so every block is compiled."""
    decl = "".join(f"  b{i} : {b};\n" + "".join(f"  b{i}_{v} : {t};\n" for v, t in io)
                   for i, (b, io) in enumerate(blocks))
    calls = "".join(f"b{i}(" + ", ".join(f"{v} := b{i}_{v}" for v, _t in io) + ");\n"
                    for i, (_b, io) in enumerate(blocks))
    return (f"PROGRAM UseLib\nVAR\n{decl}END_VAR\n{calls}END_PROGRAM\n\nCONFIGURATION Config0\n"
            "  RESOURCE Res0 ON PLC\n    TASK tMain(INTERVAL := T#10ms, PRIORITY := 0);\n"
            "    PROGRAM inst0 WITH tMain : UseLib;\n  END_RESOURCE\nEND_CONFIGURATION\n")


def _public_fbs(files):
    """[(function block, [(in-out, its type)])] of the files (internal ones too)."""
    out = []
    for f in files:
        for p in stdecl.parse_file(str(f)).pous:
            if p.kind == "FUNCTION_BLOCK":
                out.append((p.name, [(v.name, v.type.text()) for s in p.sections
                                     if s.kind == "VAR_IN_OUT" for v in s.vars]))
    return out


def _one_file(tmp_path, name, files, blocks):
    text = "".join(Path(p).read_text() + "\n" for p in files) + _program(blocks)
    f = tmp_path / f"{name}.st"
    f.write_text(text)
    return f


def _chain_names():
    """Every type, enumeration value and POU the chain library declares."""
    names = set()
    for f in CHAIN:
        u = stdecl.parse_file(str(f))
        names |= {p.name for p in u.pous} | {t.name for t in u.types}
        names |= {v for t in u.types if t.kind == "enum" for v, _c in t.values}
    return names


CASES = {"core-alone": (CORE, CORE), "chain-on-core": (CORE + CHAIN, CHAIN)}


def test_the_libraries_are_split_as_their_folders():
    assert {p.name for p in CORE} == {p.name for p in (LIB / "core").glob("*.st")}
    assert {p.name for p in CHAIN} == {p.name for p in (LIB / "chain").glob("*.st")}
    assert not list(LIB.glob("*.st")), "every .st file of st_lib/ is in core/ or chain/"
    assert {"MIP_Sender.st", "MIP_Receiver.st", "MIP_Types.st", "MIP_Version.st"} <= {p.name for p in CORE}
    assert {"MIP_SoeReader.st", "MIP_UnicosEvents.st", "MIP_ChainVersion.st"} <= {p.name for p in CHAIN}
    fbs = [b for b, _io in _public_fbs(CORE + CHAIN)]
    assert {"MIP_BufferSender", "MIP_Link", "MIP_SoeServer", "MIP_UnicosStatus"} <= set(fbs)


def test_the_core_names_nothing_of_the_chain():
    """Not in code and not in comments: the core neither uses nor documents the chain."""
    names = _chain_names()
    assert {"MIP_SoeReader", "E_MIP_ChainError", "MIP_T_UnicosTable"} <= names
    hits = [f"{f.relative_to(REPO)}:{n}: {w}" for f in CORE
            for n, line in enumerate(f.read_text().splitlines(), 1)
            for w in re.findall(r"\b[A-Za-z_]\w*\b", line) if w in names]
    assert not hits, "the core refers to the chain library:\n" + "\n".join(hits)


@pytest.mark.parametrize("case", CASES)
def test_stc_compiles_each_library_alone(case, tmp_path):
    files, mine = CASES[case]
    src = _one_file(tmp_path, case, files, _public_fbs(mine))
    r = subprocess.run([str(Path(sys.executable).parent / "stc"), "-o", str(tmp_path / "gen"),
                        str(src)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "warning" not in r.stderr.lower(), r.stderr


def test_the_chain_does_not_compile_without_the_core(tmp_path):
    """The check above is not vacuous: the chain alone misses the core's names."""
    src = _one_file(tmp_path, "chain-alone", CHAIN, _public_fbs(CHAIN))
    r = subprocess.run([str(Path(sys.executable).parent / "stc"), "-o", str(tmp_path / "gen"),
                        str(src)], capture_output=True, text=True)
    assert r.returncode != 0 and "MIP_T_BLOCK" in r.stderr, r.stderr


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("flags", [[], OPENPLC_FLAGS], ids=["plain", "openplc-flags"])
def test_matiec_compiles_each_library_alone(case, flags, tmp_path):
    exe, lib = matiec_paths()
    if not exe:
        pytest.skip("iec2c not found on PATH or in $IEC2C: matiec check not run "
                    "(set IEC2C and MATIEC_LIB to run it)")
    files, mine = CASES[case]
    src = _one_file(tmp_path, case, files, _public_fbs(mine))
    out = tmp_path / "gen"
    out.mkdir()
    r = subprocess.run([exe, *flags, "-I", lib, "-T", str(out), str(src)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert (out / "POUS.c").is_file()
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc and Path(lib, "C").is_dir():
        for c in ("Config0.c", "Res0.c"):
            p = subprocess.run([cc, "-std=gnu99", "-w", "-c", "-I", str(Path(lib, "C")), str(out / c),
                                "-o", str(tmp_path / (c + ".o"))], capture_output=True, text=True)
            assert p.returncode == 0, f"{c}: {p.stderr}"


def test_an_order_file_that_misses_a_file_is_refused_in_one_line(tmp_path):
    (tmp_path / "core").mkdir()
    (tmp_path / "core" / "import-order.txt").write_text("# comment\nMIP_A.st\n")
    with pytest.raises(LibraryError) as e:
        library_files("core", tmp_path)
    assert str(e.value).endswith("import-order.txt:2: error: MIP_A.st: no such .st file in core/")
