"""`make dist`: one release archive per library (issue 46). The core's carries the version of
MIP_Version.st in its name, holds the sources in import order, one concatenated .st that
compiles and runs, the PLCopen XML valid against the TC6 schema, the block reference, LICENSE
and CHANGELOG.md, and the Wireshark dissector with its install steps; the chain's the same for
the chain library (version MIP_ChainVersion.st), whose one-file library compiles on the core's."""
import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest
from mipprograms.common import config
from plcharness import Plc

REPO = Path(__file__).resolve().parents[2]
XSD = REPO / "build" / "docs" / "tc6_xml_v201.xsd"
MKDIST = REPO / "dist" / "mkdist.py"

PROBE_TEXT = """
PROGRAM Probe
VAR
  udiAll : UDINT;
  udiMajor : UDINT;
  udiMinor : UDINT;
  udiPatch : UDINT;
END_VAR
udiAll := MIP_Version(0);
udiMajor := MIP_Version(1);
udiMinor := MIP_Version(2);
udiPatch := MIP_Version(3);
END_PROGRAM
"""
PROBE = PROBE_TEXT + config("Probe", "p0")
CHAIN_PROBE = PROBE_TEXT.replace("MIP_Version(", "MIP_ChainVersion(") + config("Probe", "p0")


def mkdist(*args, cwd=REPO):
    return subprocess.run([sys.executable, str(MKDIST), *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def probe_version(lib, tmp_path, before=(), probe=PROBE):
    """(MAJOR, MINOR, PATCH, whole) as MIP_Version (or the probe's function) returns them in a
    program built with lib (after the files `before`)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    prog = tmp_path / "probe.st"
    prog.write_text(probe)
    with Plc.build([*before, lib, prog], workdir=tmp_path / "b", compiler="stc") as plc:
        plc.scan()
        return tuple(plc[f"Probe.udi{k}"] for k in ("Major", "Minor", "Patch", "All"))


@pytest.fixture(scope="module")
def archives(tmp_path_factory):
    """{archive name: (out dir, .tar.gz, unpacked top folder)} of both libraries' releases."""
    assert XSD.exists(), f"{XSD.relative_to(REPO)} missing: run `make {XSD.relative_to(REPO)}`"
    out = tmp_path_factory.mktemp("dist")
    r = mkdist("--xsd", XSD, "-o", out)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        f"{n}.{ext}" for n in re.findall(r"dist: wrote \S+/(\S+)\.tar\.gz", r.stdout)
        for ext in ("tar.gz", "zip"))
    tops = {}
    for tgz in out.glob("*.tar.gz"):
        unpacked = tmp_path_factory.mktemp("unpacked")
        with tarfile.open(tgz) as t:
            t.extractall(unpacked, filter="data")
        (top,) = list(unpacked.iterdir())
        tops[tgz.name] = (out, tgz, top)
    assert len(tops) == 2, list(out.iterdir())
    return tops


@pytest.fixture(scope="module")
def archive(archives):
    """The core library's release."""
    (core,) = [a for n, a in archives.items() if re.fullmatch(r"mip-logger-[\d.]+\.tar\.gz", n)]
    return core


@pytest.fixture(scope="module")
def chain_archive(archives):
    (chain,) = [a for n, a in archives.items() if n.startswith("mip-logger-chain-")]
    return chain


def blocks_md_order(page="blocks.md"):
    text = (REPO / "docs" / page).read_text()
    return re.findall(r"^\d+\. `(st_lib/[^`]+)`$", text, re.M)


def test_archive_name_carries_the_version_that_mip_version_returns(archive, tmp_path):
    _, tgz, top = archive
    m = re.fullmatch(r"mip-logger-(\d+)\.(\d+)\.(\d+)\.tar\.gz", tgz.name)
    assert m, tgz.name
    major, minor, patch = map(int, m.groups())
    assert top.name == f"mip-logger-{major}.{minor}.{patch}"
    # the version as a PLC program sees it, built from the archive's one-file library
    assert probe_version(top / f"{top.name}.st", tmp_path) == \
        (major, minor, patch, major * 10000 + minor * 100 + patch)
    r = mkdist("--version")
    assert r.returncode == 0 and r.stdout.strip() == f"{major}.{minor}.{patch}"


def test_archive_holds_sources_in_import_order_and_the_product_files(archive):
    out, tgz, top = archive
    with tarfile.open(tgz) as t:
        names = [n[len(top.name) + 1:] for n in t.getnames()]
    order = blocks_md_order()
    assert sorted(order) == sorted(f"st_lib/core/{p.name}" for p in (REPO / "st_lib" / "core").glob("*.st"))
    assert [n for n in names if n.startswith("st_lib/")] == order
    for n in order:
        assert (top / n).read_bytes() == (REPO / n).read_bytes(), n
    for n in ("LICENSE", "CHANGELOG.md"):
        assert (top / n).read_bytes() == (REPO / n).read_bytes(), n
    assert (top / "blocks.md").read_text() == (REPO / "docs" / "blocks.md").read_text()
    assert "Soe" not in " ".join(names) and "Unicos" not in " ".join(names), names
    readme = (top / "README.txt").read_text()
    assert [line.split(". ", 1)[1] for line in readme.splitlines()
            if re.match(r"\s+\d+\. st_lib/", line)] == order
    # the one-file library: the sources in import order, each complete
    one = (top / f"{top.name}.st").read_text()
    positions = [one.index((REPO / n).read_text().rstrip("\n")) for n in order]
    assert positions == sorted(positions)
    # the zip has the same members with the same bytes
    zpath = out / tgz.name.replace(".tar.gz", ".zip")
    with zipfile.ZipFile(zpath) as z, tarfile.open(tgz) as t:
        assert z.namelist() == t.getnames()
        for n in z.namelist():
            assert z.read(n) == t.extractfile(n).read(), n


def test_the_chain_archive_is_the_chain_library_on_the_core(archive, chain_archive, tmp_path):
    """mip-logger-chain-X.Y.Z: the chain's files in their import order (docs/blocks-chain.md),
    its version in the name (what MIP_ChainVersion returns), the one-file .st and .scl that
    build on the core archive's, PLCopen XML valid against TC6 with every POU, its block
    reference, and the core version it needs in README.txt; no glue, no core file."""
    from stc.scl_out import generate_files
    out, tgz, top = chain_archive
    _, _, core_top = archive
    m = re.fullmatch(r"mip-logger-chain-(\d+)\.(\d+)\.(\d+)\.tar\.gz", tgz.name)
    assert m and top.name == tgz.name[:-len(".tar.gz")]
    major, minor, patch = map(int, m.groups())
    assert mkdist("--version", "chain").stdout.strip() == f"{major}.{minor}.{patch}"
    with tarfile.open(tgz) as t:
        names = [n[len(top.name) + 1:] for n in t.getnames()]
    order = blocks_md_order("blocks-chain.md")
    assert sorted(order) == sorted(f"st_lib/chain/{p.name}" for p in (REPO / "st_lib" / "chain").glob("*.st"))
    assert [n for n in names if n.startswith("st_lib/")] == order
    assert not [n for n in names if n.startswith(("glue/", "twincat/", "wireshark/"))], names
    for n in order:
        assert (top / n).read_bytes() == (REPO / n).read_bytes(), n
    assert (top / "blocks.md").read_text() == (REPO / "docs" / "blocks-chain.md").read_text()
    readme = (top / "README.txt").read_text()
    assert f"Needs the core library mip-logger {core_top.name.split('-')[-1]} " in readme
    assert [line.split(". ", 1)[1] for line in readme.splitlines()
            if re.match(r"\s+\d+\. st_lib/", line)] == order
    core_st = core_top / f"{core_top.name}.st"
    assert probe_version(top / f"{top.name}.st", tmp_path / "st", [core_st], CHAIN_PROBE) == \
        (major, minor, patch, major * 10000 + minor * 100 + patch)
    # SCL: what the generator writes for the chain's files (read with the core's), and it runs
    core_order = blocks_md_order()
    fresh = generate_files([str(REPO / f) for f in core_order + order], f"{major}.{minor}.{patch}")
    want = [f"scl/{Path(f).stem}.scl" for f in order if str(REPO / f) in fresh]
    assert [n for n in names if n.startswith("scl/")] == want and want
    assert probe_version(top / f"{top.name}.scl", tmp_path / "scl", [core_top / f"{core_top.name}.scl"],
                         CHAIN_PROBE)[:3] == (major, minor, patch)
    xml = top / f"{top.name}.xml"
    r = subprocess.run([sys.executable, str(REPO / "docs/tools/plcopen_export.py"),
                        "--validate", str(XSD), str(xml)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    text = xml.read_text()
    for n in order:
        for pou in re.findall(r"^(?:FUNCTION_BLOCK|FUNCTION) (\w+)", (REPO / n).read_text(), re.M):
            assert f'<pou name="{pou}"' in text, pou
    assert '<pou name="MIP_Sender"' not in text


def test_archive_carries_no_kit(archive):
    """docs/test-kit.md, "Not (yet) in the kit": the st_lib release archive does not carry the
    kit (it has its own, make kit-dist). Fails when it does: change that page."""
    out, tgz, top = archive
    with tarfile.open(tgz) as t:
        names = [n[len(top.name) + 1:] for n in t.getnames()]
    assert not [n for n in names if n.startswith("kit/") or "mipkit" in n], names


def test_one_file_library_translates_with_stc(archive, tmp_path):
    _, _, top = archive
    stc = Path(sys.executable).parent / "stc"
    r = subprocess.run([str(stc), "-o", str(tmp_path), str(top / f"{top.name}.st")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "POUS.c").is_file()


def test_scl_library_is_generated_complete_and_runs(archive, tmp_path):
    """scl/*.scl: one file per st_lib file with a block or a STRUCT type (a PLC data type in
    TIA; enumerations and array types the blocks carry themselves), in import order, exactly
    what the generator writes from st_lib; the one-file .scl translates as SCL and runs (MIP_Version)."""
    from stc.scl_out import generate_files
    _, tgz, top = archive
    version = top.name.split("-")[-1]
    with tarfile.open(tgz) as t:
        names = [n[len(top.name) + 1:] for n in t.getnames()]
    order = blocks_md_order()
    fresh = generate_files([str(REPO / f) for f in order], version)
    want = [f"scl/{Path(f).stem}.scl" for f in order if str(REPO / f) in fresh]
    assert [n for n in names if n.startswith("scl/")] == want
    assert len(want) == sum(1 for f in order if re.search(
        r"^\s*FUNCTION(_BLOCK)?\s|:\s*STRUCT\b", (REPO / f).read_text(), re.M))
    for f in order:
        if str(REPO / f) in fresh:
            assert (top / f"scl/{Path(f).stem}.scl").read_text() == fresh[str(REPO / f)], f
    one = top / f"{top.name}.scl"
    major, minor, patch = map(int, version.split("."))
    assert one.read_text().count(f"VERSION : {major}.{minor}\n") == \
        one.read_text().count("\nBEGIN\n") + len(re.findall(r'^TYPE "', one.read_text(), re.M))
    assert f"{top.name}.scl" in (top / "README.txt").read_text()
    assert probe_version(one, tmp_path)[:3] == (major, minor, patch)


def test_plcopen_xml_is_valid_and_complete(archive):
    _, _, top = archive
    xml = top / f"{top.name}.xml"
    r = subprocess.run([sys.executable, str(REPO / "docs/tools/plcopen_export.py"),
                        "--validate", str(XSD), str(xml)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    text = xml.read_text()
    version = top.name.split("-")[-1]
    assert f'productVersion="{version}"' in text
    for n in blocks_md_order():
        for pou in re.findall(r"^(?:FUNCTION_BLOCK|FUNCTION) (\w+)", (REPO / n).read_text(), re.M):
            assert f'<pou name="{pou}"' in text, pou


def test_license_is_mit_with_the_authors():
    text = (REPO / "LICENSE").read_text()
    assert text.startswith("MIT License")
    assert "the mip-logger authors" in text


def _copy_product(tmp_path):
    repo = tmp_path / "repo"
    shutil.copytree(REPO / "st_lib", repo / "st_lib")
    shutil.copytree(REPO / "dist", repo / "dist")
    for n in ("LICENSE", "CHANGELOG.md"):
        shutil.copy(REPO / n, repo / n)
    return repo


def test_version_without_changelog_entry_is_refused_in_one_line(tmp_path):
    repo = _copy_product(tmp_path)
    v = repo / "st_lib" / "core" / "MIP_Version.st"
    v.write_text(re.sub(r"(uPatch : UINT := )\d+;", r"\g<1>97;", v.read_text()))
    r2 = subprocess.run([sys.executable, str(repo / "dist" / "mkdist.py"), "-o",
                         str(tmp_path / "out")], cwd=repo, capture_output=True, text=True)
    assert r2.returncode == 1
    assert r2.stderr.count("\n") == 1 and "Traceback" not in r2.stderr
    assert "CHANGELOG.md: error: no entry '## [" in r2.stderr and ".97]" in r2.stderr
    assert not (tmp_path / "out").exists()


def test_missing_version_constant_is_one_line_with_the_file(tmp_path):
    repo = _copy_product(tmp_path)
    v = repo / "st_lib" / "core" / "MIP_Version.st"
    v.write_text(v.read_text().replace("uMinor : UINT", "uMinorX : UINT"))
    r = subprocess.run([sys.executable, str(repo / "dist" / "mkdist.py"), "--version"],
                       cwd=repo, capture_output=True, text=True)
    assert r.returncode == 1
    assert r.stderr == ("st_lib/core/MIP_Version.st: error: no constant uMinor : UINT := N; "
                        "(the version is uMajor.uMinor.uPatch)\n")


def _mini_repo(tmp_path, core_order, chain=None):
    for lib in ("core", "chain"):
        (tmp_path / "st_lib" / lib).mkdir(parents=True)
    (tmp_path / "st_lib" / "core" / "A_User.st").write_text(
        "FUNCTION_BLOCK A_User\nVAR_OUTPUT x : UDINT; END_VAR\nx := Z_Helper(1);\n"
        "END_FUNCTION_BLOCK\n")
    (tmp_path / "st_lib" / "core" / "Z_Helper.st").write_text(
        "FUNCTION Z_Helper : UDINT\nVAR_INPUT u : UINT; END_VAR\nZ_Helper := UINT_TO_UDINT(u);\n"
        "END_FUNCTION\n")
    (tmp_path / "st_lib" / "core" / "import-order.txt").write_text("# order\n" + "\n".join(core_order) + "\n")
    (tmp_path / "st_lib" / "chain" / "import-order.txt").write_text("C_Chain.st\n" if chain else "")
    if chain:
        (tmp_path / "st_lib" / "chain" / "C_Chain.st").write_text(chain)


def test_a_function_called_in_a_body_is_imported_before_its_caller(tmp_path):
    """The import order (st_lib/<library>/import-order.txt: docs/blocks.md, the archive, the
    one-file library) also follows FUNCTION calls, not only declared types: matiec reads one
    file front to back. mkdist refuses an order file that lists a caller first, in one line."""
    from mipdist import mkdist as mkdist_module
    _mini_repo(tmp_path / "good", ["Z_Helper.st", "A_User.st"])
    order, _ = mkdist_module.import_order(tmp_path / "good")
    assert order == ["st_lib/core/Z_Helper.st", "st_lib/core/A_User.st"]
    _mini_repo(tmp_path / "bad", ["A_User.st", "Z_Helper.st"])
    r = mkdist("--repo", tmp_path / "bad", "--import-order", "core")
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stderr == ("st_lib/core/import-order.txt:2: error: A_User.st uses Z_HELPER of "
                        "st_lib/core/Z_Helper.st: list Z_Helper.st before it\n"), r.stderr


def test_a_core_that_uses_the_chain_and_an_unlisted_file_are_refused(tmp_path):
    from mipdist import mkdist as mkdist_module
    _mini_repo(tmp_path / "dep", ["Z_Helper.st", "A_User.st", "B_Core.st"],
               chain="FUNCTION C_Chain : UDINT\nVAR_INPUT u : UINT; END_VAR\nC_Chain := 0;\nEND_FUNCTION\n")
    (tmp_path / "dep" / "st_lib" / "core" / "B_Core.st").write_text(
        "FUNCTION B_Core : UDINT\nVAR_INPUT u : UINT; END_VAR\nB_Core := C_Chain(u);\nEND_FUNCTION\n")
    with pytest.raises(mkdist_module.DistError) as e:
        mkdist_module.import_order(tmp_path / "dep", "core")
    assert str(e.value) == ("st_lib/core/B_Core.st: error: B_Core.st uses C_CHAIN of "
                            "st_lib/chain/C_Chain.st: the core library uses no name of the chain library")
    _mini_repo(tmp_path / "unlisted", ["Z_Helper.st"])
    with pytest.raises(mkdist_module.DistError) as e:
        mkdist_module.import_order(tmp_path / "unlisted", "core")
    assert str(e.value) == ("st_lib/core/import-order.txt: error: st_lib/core/A_User.st is not listed "
                            "(every .st file of st_lib/core/ is, in import order)")


def test_the_archives_are_reproducible(archive, tmp_path):
    out, tgz, _ = archive
    r = mkdist("-o", tmp_path)
    assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 4 and sorted(p.name for p in tmp_path.iterdir()) == names
    for name in names:
        assert (tmp_path / name).read_bytes() == (out / name).read_bytes(), name


def test_the_wireshark_dissector_ships_and_installs_as_the_readme_says(archive, tmp_path):
    """wireshark/mipmb.lua (docs/wireshark.md) is in the archive, and copied into the personal
    Lua plugins folder the README names, tshark knows its fields (without it: it does not)."""
    out, tgz, top = archive
    lua = top / "wireshark" / "mipmb.lua"
    assert lua.read_bytes() == (REPO / "dist" / "wireshark" / "mipmb.lua").read_bytes()
    readme = (top / "README.txt").read_text()
    assert "~/.local/lib/wireshark/plugins/" in readme
    assert "tshark -X lua_script:wireshark/mipmb.lua -r CAPTURE" in readme
    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("tshark is not installed (Debian package tshark)")
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}

    def fields():
        r = subprocess.run([tshark, "-G", "fields"], capture_output=True, text=True, env=env,
                           timeout=120)
        assert r.returncode == 0, r.stderr
        return r.stdout

    assert "\tmipmb.record\t" not in fields()
    plugins = tmp_path / ".local" / "lib" / "wireshark" / "plugins"
    plugins.mkdir(parents=True)
    shutil.copy(lua, plugins)
    assert "\tmipmb.record\t" in fields()


def test_the_vendor_glue_ships_and_compiles_from_the_archive(archive, tmp_path):
    """glue/<family>/ (issue 36) holds dist/glue's files byte for byte, the README names it,
    and each family's glue translates from the archive's own files (the one-file library, the
    glue, the stand-ins of CI for the vendor's client blocks)."""
    from stc import cli
    out, tgz, top = archive
    shipped = sorted(str(p.relative_to(top)) for p in (top / "glue").rglob("*") if p.is_file())
    assert shipped == sorted(str(p.relative_to(REPO / "dist"))
                             for p in (REPO / "dist" / "glue").rglob("*") if p.is_file())
    assert "glue/twincat/MIP_TcModbusIo.twincat.st" in shipped
    for n in shipped:
        assert (top / n).read_bytes() == (REPO / "dist" / n).read_bytes(), n
    assert "glue/<family>/" in (top / "README.txt").read_text()
    for family, standin in (("twincat", "twincat/Tc2_ModbusSrv.twincat.st"),
                            ("codesys", "codesys/ModbusFB.codesys.st")):
        assert f"glue/{family}/README.md" in shipped
        files = [top / f"{top.name}.st", *sorted((top / "glue" / family).glob(f"*.{family}.st")),
                 REPO / "standins" / "StandIn_Channel.twincat.st", REPO / "standins" / standin]
        assert cli.main(["-o", str(tmp_path / family)] + [str(f) for f in files]) == 0, family
    # S7: the archive's SCL library, the glue in SCL, the MB_CLIENT stand-in
    assert "glue/s7/README.md" in shipped
    files = [top / f"{top.name}.scl", *sorted((top / "glue" / "s7").glob("*.scl")),
             REPO / "standins" / "StandIn_Channel.twincat.st",
             REPO / "standins" / "s7" / "MB_CLIENT.codesys.st"]
    assert cli.main(["-o", str(tmp_path / "s7")] + [str(f) for f in files]) == 0
