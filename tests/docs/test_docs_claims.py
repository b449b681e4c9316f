"""Statements in the docs that drift when the code changes (issue 44): lists of what exists
(folders, st_lib files, blocks) are compared with the tree, and each limitation a page states
("not yet", "needs X", "only", "cannot") is either compared here with the code it describes or
named with the test that fails when the limitation goes away (LIMITATIONS below)."""
from __future__ import annotations

import re
import subprocess

import pytest
from mipdist import mkdist

from docs_helpers import REPO

NUMBERS = {w: i for i, w in enumerate("zero one two three four five six seven eight nine ten "
                                      "eleven twelve".split())}


def section(text, heading):
    """The text under a markdown heading, up to the next heading of any level."""
    m = re.search(rf"^#+ {re.escape(heading)}\s*$(.*?)(?=^#|\Z)", text, re.M | re.S)
    assert m, f"no section {heading!r}"
    return m.group(1)


def table_first_column(text, header):
    """The first cells of the markdown table whose header row starts with `| header |`."""
    lines = text.splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith(f"| {header} |"))
    cells = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells.append(line.split("|")[1].strip())
    return cells


def public_blocks():
    """The function blocks of st_lib an application calls: FUNCTION_BLOCKs whose header does
    not call them internal."""
    out = []
    for f in sorted((REPO / "st_lib").glob("*/*.st")):
        text = f.read_text()
        fb = re.search(r"^FUNCTION_BLOCK (\w+)", text, re.M)
        purpose = re.search(r"@purpose\s+(\S+)", text)
        if fb and not (purpose and purpose.group(1).startswith("Internal")):
            out.append(fb.group(1))
    return out


def tracked_top_folders():
    out = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True,
                         timeout=60)
    if out.returncode != 0:
        pytest.skip(f"not a git checkout (git ls-files: {out.stderr.strip()[:80]})")
    return {p.split("/")[0] for p in out.stdout.splitlines()
            if "/" in p and not p.startswith(".git")}


# ----------------------------------------------------------------------- lists of what exists

def test_readme_folder_table_lists_every_top_level_folder():
    named = set()
    for cell in table_first_column((REPO / "README.md").read_text(), "folder"):
        named |= {m.rstrip("/") for m in re.findall(r"`([^`]+/)`", cell)}
    named = {n.split("/")[0] for n in named}
    folders = tracked_top_folders()
    assert folders - named == set(), \
        f"README.md's folder table does not name {sorted(folders - named)}"
    assert named - folders == set(), \
        f"README.md's folder table names {sorted(named - folders)}, which the checkout lacks"


def test_st_lib_readme_table_lists_every_file_in_import_order():
    order = [f.split("st_lib/", 1)[1] for lib in ("core", "chain")
             for f in mkdist.import_order(REPO, lib)[0]]
    rows = [c.strip("`") for c in table_first_column((REPO / "st_lib" / "README.md").read_text(),
                                                    "file")]
    assert [r for r in rows if r.endswith(".st")] == order, (
        "st_lib/README.md's file table is not every st_lib/*/*.st in the import order "
        f"(`dist/mkdist.py --import-order`): missing {sorted(set(order) - set(rows))}, "
        f"extra {sorted(set(rows) - set(order) - {'PROTOCOL.md', 'CONVENTIONS.md'})}")


@pytest.mark.parametrize("page,where", [
    ("st_lib/README.md", None),
    ("docs/README.md", "- **`st_lib/`**"),
    ("README.md", "| `st_lib/` |"),
])
def test_pages_name_every_public_block(page, where):
    text = (REPO / page).read_text()
    if where is None:       # st_lib/README.md: its introduction, before the file table
        part = text.split("\n## ", 1)[0]
    else:                   # the paragraph (or table row) that introduces st_lib/
        i = text.index(where)
        part = text[i:text.find("\n- **", i + 1) if where.startswith("-") else text.find("\n", i)]
    missing = [b for b in public_blocks() if b not in part]
    assert not missing, f"{page}: where it introduces the blocks it does not name {missing}"
    for word in re.findall(r"\b(\w+) blocks\b", part, re.I):
        n = NUMBERS.get(word.lower(), int(word) if word.isdigit() else None)
        if n is not None:
            assert n == len(public_blocks()), \
                f"{page}: says {word} blocks; st_lib has {len(public_blocks())}: {public_blocks()}"


# ------------------------------------------------------------ stated limitations, against code

def test_kit_limitations_say_nothing_of_retain_that_plcrt_build_does():
    """docs/test-kit.md, "Not (yet) in the kit": it said warm restarts need stc (matiec builds
    keeping no RETAIN) after plcrt-build had learnt to keep them (commit cdf4aba;
    tests/runtime/test_rt_matiec.py runs a matiec build's warm restart where iec2c is)."""
    from plcharness import build
    keeps = callable(getattr(build, "matiec_retained", None))
    limits = section((REPO / "docs" / "test-kit.md").read_text(), "Not (yet) in the kit")
    claims = re.search(r"RETAIN|warm (or kill -9 )?restart", limits)
    if keeps:
        assert not claims, ("docs/test-kit.md, Not (yet) in the kit: states a RETAIN limitation, "
                            f"but plcrt-build keeps RETAIN of matiec builds: {claims.group(0)!r}")
    else:
        assert claims, "plcrt-build keeps no RETAIN of matiec builds: say so in the kit's limits"


def test_guarantee_table_window_row_matches_mip_sender():
    """docs/protocol.md's guarantee table said window 2 runs "not `xRetained`"; MIP_Sender's
    header says under which settings uWindow 2 falls back to 1 (tests/st_lib/
    test_lib_window_warm.py runs window 2 with xRetained through warm restarts)."""
    sender = (REPO / "st_lib" / "core" / "MIP_Sender.st").read_text()
    row = re.search(r"^\s*\| uWindow .*$", sender, re.M).group(0)
    fallback = re.search(r"PROTOCOL\.md P27;([^)]*)\)", row).group(1)
    table = (REPO / "docs" / "protocol.md").read_text()
    cell = re.search(r"^\| `uWindow` = 2 \| ([^|]*)\|", table, re.M).group(1)
    for word in ("spontaneous", "dynamic"):
        assert (word in fallback) == (word in cell), \
            f"docs/protocol.md's uWindow row and MIP_Sender's uWindow ({fallback.strip()}) differ on {word}"
    restricted = "retain" in fallback.lower()
    assert ("not `xRetained`" in cell) == restricted, (
        f"docs/protocol.md's uWindow row says {cell.strip()!r}; MIP_Sender's uWindow falls back "
        f"to 1 for: {fallback.strip()}")


def test_guarantee_table_cold_restart_row_names_what_the_caller_must_do():
    """The cold-restart row holds only for a caller that acknowledges after the hand-over
    (tests/chain/test_chain_central_cold.py runs it with the note peer against plc/central.st,
    with and without the hand-over)."""
    table = (REPO / "docs" / "protocol.md").read_text()
    row = re.search(r"^\| cold restart \|.*$", table, re.M).group(0)
    assert "xAckByCaller" in row and "xRecordProcessed" in row
    gen = (REPO / "plc" / "central.st").read_text() + (REPO / "plc" / "PLC_Logger.st").read_text()
    assert "xAckByCaller := stSet.xHandOver" in gen and "(stPar.wFlags AND 16#0020)" in gen, \
        "plc/central.st no longer hands over with flags bit 5: change the guarantee table's row"
    assert (REPO / "tests" / "chain" / "test_chain_central_cold.py").is_file()


def test_plc_readme_names_every_program():
    """plc/README.md said gen_programs.py "writes the five programs" when it wrote eight: its
    file table names every plc/*.st, and no count of programs."""
    text = (REPO / "plc" / "README.md").read_text()
    cells = " ".join(table_first_column(text, "file"))
    missing = [p.name for p in sorted((REPO / "plc").glob("*.st")) if f"`{p.name}`" not in cells]
    assert not missing, f"plc/README.md's file table does not name {missing}"
    for word in re.findall(r"\bthe (\w+) programs\b", text):
        assert word.lower() not in NUMBERS, f"plc/README.md counts 'the {word} programs'"


def test_translator_not_supported_list_is_the_reject_corpus():
    """translator/README.md's "Not supported:" list: each construct has a file in
    tests/translator/reject/ (run by test_stc_corpus.py::test_reject, which fails once stc
    accepts it: then take it off the list)."""
    corpus = {
        "WSTRING": ["unsupported_wstring.st"],
        "`STRING[n]`": ["string_20.st"],
        "TIME_TO_STRING / STRING_TO_TIME": ["unsupported_time_to_string.st",
                                            "unsupported_string_to_time.st"],
        "DATE/TOD/DT": ["unsupported_date.st", "unsupported_tod.st", "unsupported_dt.st"],
        "SINGLE tasks": ["unsupported_single_task.st"],
        "program instance arguments": ["unsupported_program_arguments.st"],
        "FB instances as VAR_GLOBAL": ["unsupported_fb_global.st"],
    }
    text = (REPO / "translator" / "README.md").read_text()
    listed = re.search(r"^Not supported: (.*)\.$", text, re.M).group(1).split(", ")
    assert listed == list(corpus), f"translator/README.md's Not supported list changed: {listed}"
    assert "A FUNCTION returning a STRUCT is\nnot implemented by stc" in text
    corpus["FUNCTION returning a STRUCT"] = ["function_returns_struct.st"]
    for what, files in corpus.items():
        for f in files:
            assert (REPO / "tests" / "translator" / "reject" / f).is_file(), f"{what}: {f}"


def test_kit_openplc_configs_get_no_address_check(tmp_path):
    """docs/test-kit.md: an OpenPLC mbconfig.cfg is loaded, but the address check applies to
    plcrt configs only: a .cfg whose devices land where the program declares nothing passes."""
    from types import SimpleNamespace

    from mipkit.net import check_config
    gen = tmp_path / "build" / "gen"
    gen.mkdir(parents=True)
    (gen / "LOCATED_VARIABLES.h").write_text("__LOCATED_VAR(INT,__MW0,M,W,0)\n")
    cfg = tmp_path / "mbconfig.cfg"
    cfg.write_text((REPO / "plc" / "openplc" / "central-mbconfig.cfg").read_text())
    conf = tmp_path / "plcrt.conf"
    conf.write_text("[device mdp]\nhost = 127.0.0.1\nport = 1502\n[read up]\ndevice = mdp\ntable = holding\n"
                    "start = 198\nsize = 125\nimage = %IW100\ntrigger = %QX1.0\n")
    build = SimpleNamespace(outdir=tmp_path / "build")
    with pytest.raises(Exception, match="the program declares none of %IW100"):
        check_config(build, conf)          # the check works on a plcrt config ...
    check_config(build, cfg)               # ... and does not look into an mbconfig.cfg


def test_kit_stand_ins_have_no_answer_delay():
    """docs/test-kit.md: the chain's stand-ins answer at once. Their kit classes take no delay
    (a parameter named like one would end the limitation: change that page)."""
    import inspect

    from mipkit import ends
    for cls in (ends.KitUnicos, ends.KitScada, ends.KitRelay):
        params = [p for p in inspect.signature(cls.__init__).parameters
                  if re.search(r"delay|latency|answer_ms|response", p)]
        assert not params, f"{cls.__name__} takes {params}: docs/test-kit.md says they answer at once"


# Each item of docs/test-kit.md's "Not (yet) in the kit", with what keeps it true: a test that
# fails when the limitation goes away, or why none can.
KIT_LIMITS = {
    "does not carry the kit": "tests/dist/test_dist.py::test_archive_carries_no_kit",
    "the address check above applies":
        "tests/docs/test_docs_claims.py::test_kit_openplc_configs_get_no_address_check",
    "`no_xerror` samples a located address":
        "why: the kit looks at the PLC between its steps; a sampler cannot see what rose and "
        "fell between two looks (the program's latch is the remedy the page gives)",
    "The chain's stand-ins answer at once": "tests/docs/test_docs_claims.py::test_kit_stand_ins_have_no_answer_delay",
    "`relay.missing(...)` and `expect.reached` check the scripted events":
        "why: generated events (rate, burst) are drawn inside the emulator's relay, which keeps "
        "no list of them for the kit to compare one by one; only its counters are read",
    "A relay or control system is given before the network runs":
        "tests/kit/test_kit_ends.py::test_relay_bad_input_is_one_line",
}


def test_every_kit_limitation_is_tied_to_a_test_or_says_why():
    limits = section((REPO / "docs" / "test-kit.md").read_text(), "Not (yet) in the kit")
    items = [re.sub(r"\s+", " ", i) for i in re.split(r"\n- ", "\n" + limits.strip())[1:]]
    for item in items:
        keys = [k for k in KIT_LIMITS if k in item]
        assert len(keys) == 1, (f"docs/test-kit.md, Not (yet) in the kit: {item[:90]!r} is tied "
                                f"to no test here (add it to KIT_LIMITS)")
    for key, tie in KIT_LIMITS.items():
        assert any(key in i for i in items), f"KIT_LIMITS: {key!r} is no longer on the page"
        if tie.startswith("why: "):
            continue
        path, name = tie.split("::")
        assert re.search(rf"^def {name}\(", (REPO / path).read_text(), re.M), tie


def test_central_many_is_not_retain_as_plc_readme_says():
    """plc/README.md: "This program is not RETAIN (warm restarts are covered by central.st)"."""
    text = re.sub(r"\s+", " ", (REPO / "plc" / "README.md").read_text())
    assert "This program is not RETAIN" in text
    for f in ("central_many.st", "image/central_many_io.st"):    # the logic, its image
        assert "RETAIN" not in re.sub(r"\(\*.*?\*\)", "", (REPO / "plc" / f).read_text(), flags=re.S), \
            f"plc/{f} is RETAIN now: change plc/README.md"
    assert "VAR RETAIN\n  app : CentralLogic;" in (REPO / "plc" / "image" / "central_io.st").read_text()


# The other limitations the pages state (the sweep of issue 44: "not supported / not yet / needs
# X / only / cannot" in docs/ and the READMEs), each with the test that fails when it goes away,
# or why no test here can. Statements about the vendors' products (stock OpenPLC's 400 registers,
# its fixed slave_id, Modbus frame sizes) are facts of those products, checked where they are
# stated (openplc_limits.py, the runtime's config errors), and are not listed.
OTHER_LIMITS = [
    ("translator/README.md", "Not supported: WSTRING",
     "tests/docs/test_docs_claims.py::test_translator_not_supported_list_is_the_reject_corpus"),
    ("docs/protocol.md", "| `uWindow` = 2 | pipelined",
     "tests/docs/test_docs_claims.py::test_guarantee_table_window_row_matches_mip_sender"),
    ("docs/protocol.md", "A caller that acknowledges on receipt into volatile memory",
     "tests/chain/test_chain_central_cold.py::test_central_without_handover_cold_restart_loses_the_acknowledged_transfer"),
    ("plc/README.md", "This program is not RETAIN",
     "tests/docs/test_docs_claims.py::test_central_many_is_not_retain_as_plc_readme_says"),
    ("docs/chain.md", "Not tried on a PLC other than plcrt.",
     "why: no other PLC runtime is on the project's machines or CI's (vendor runtimes are commercial)"),
    ("docs/chain.md", "**Not tried against WinCC OA.**",
     "why: WinCC OA is a commercial product, on no machine of the project"),
    ("peers/README.md", "Not tried against WinCC OA.",
     "why: WinCC OA is a commercial product, on no machine of the project"),
    ("docs/plcopen.md", "Not tested: an import into a particular vendor IDE.",
     "why: the vendor IDEs are commercial Windows programs, on no machine of the project"),
    ("docs/wiring-codesys.md", "CI cannot run CODESYS.", "why: CODESYS is commercial; its stand-in is tested"),
    ("docs/wiring-twincat.md", "CI cannot run TwinCAT.", "why: TwinCAT is commercial; its stand-in is tested"),
    ("docs/wiring-s7.md", "CI cannot run an S7.", "why: an S7 is hardware; its stand-in is tested"),
    ("README.md", "run where `iec2c` is on `PATH` and are skipped with that reason where it is not",
     "why: matiec is in no package registry (the README says how to build it); tests/conftest.py skips with the reason"),
]


@pytest.mark.parametrize("page,words,tie", OTHER_LIMITS, ids=[f"{p}:{w[:30]}" for p, w, _ in OTHER_LIMITS])
def test_stated_limitation_is_still_stated_and_tied(page, words, tie):
    """The registry above stays true: the statement is still on its page (else it went away:
    take it off the list), and its test exists."""
    text = re.sub(r"\s+", " ", (REPO / page).read_text())
    assert words in text, f"{page} no longer says {words!r}: update OTHER_LIMITS"
    if not tie.startswith("why: "):
        path, name = tie.split("::")
        assert re.search(rf"^def {name}\(", (REPO / path).read_text(), re.M), tie
