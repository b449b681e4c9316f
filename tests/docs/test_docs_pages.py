"""The guide's pages: every relative link and image resolves (they must work on a plain Git
host), and the facts the pages state about the code agree with the code."""
import re

import pytest

from docs_helpers import REPO

DOCS = REPO / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "tools" not in p.parts)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def anchors(path):
    """GitHub-style heading anchors of a Markdown file."""
    out = set()
    for line in path.read_text().splitlines():
        if line.startswith("#"):
            h = line.lstrip("#").strip().lower()
            h = re.sub(r"[^\w\- ]", "", h).replace(" ", "-")
            out.add(h)
    return out


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_resolve(page):
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    for target in LINK.findall(text):
        if re.match(r"^[a-z]+:", target):
            continue
        path, _, frag = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        assert dest.exists(), f"{page.relative_to(REPO)}: broken link {target}"
        if frag and dest.suffix == ".md":
            assert frag in anchors(dest), f"{page.relative_to(REPO)}: no heading #{frag} in {path}"


def test_index_links_every_page():
    index = (DOCS / "README.md").read_text()
    for p in PAGES:
        if p.parent == DOCS and p.name != "README.md":
            assert f"({p.name})" in index, f"docs/README.md does not link {p.name}"


def test_station_status_bits_match_the_emulator():
    """docs/protocol.md lists the MDP station-status bits the emulator defines."""
    hdr = (REPO / "emulator" / "include" / "mipemu.h").read_text()
    bits = {int(v, 16).bit_length() - 1 for v in re.findall(r"#define MIPEMU_ST_\w+ 0x([0-9A-F]+)", hdr)}
    text = (DOCS / "protocol.md").read_text()
    table = text[text.index("Station status"):]
    for b in sorted(bits):
        assert re.search(rf"^\| {b} \|", table, re.M), f"station-status bit {b} not documented"


def test_register_addresses_match_the_emulator_readme():
    """The register map rows of docs/protocol.md name the same addresses as emulator/README.md."""
    emu = (REPO / "emulator" / "README.md").read_text()
    ours = (DOCS / "protocol.md").read_text()
    for addr in ("2000", "2001–2148", "2198", "2199", "2200–2347", "10–157", "198", "199",
                 "200–347"):
        assert f"| {addr} |" in emu and f"| {addr} |" in ours, addr


def test_glossary_has_the_notes_terms():
    text = (DOCS / "protocol.md").read_text()
    glossary = text[text.index("Glossary"):]
    for term in ("Datensatzzähler", "Bestätigungszähler", "Lesestatus", "Schreibdaten unbestätigt",
                 "Schreibdaten warten", "Neue Lesedaten", "Außenstation", "Zentrale"):
        assert f"| {term}" in glossary, term
