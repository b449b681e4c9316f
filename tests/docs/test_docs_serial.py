"""docs/serial.md's numbers come from one arithmetic (probe/mipprobe/sizing.py): the cost of an
exchange and the tTimeout table are compared with it, the table's rule with the demo's, and the
table's effect is run in the co-simulation (issue 38, item 7)."""
import math
import re
import tempfile
from pathlib import Path

from docs_helpers import REPO

from mipcosim import programs as L
from mipcosim.cli import link_timeout_ms as demo_link_timeout_ms
from mipprobe.sizing import exchange_s, link_timeout_ms, timeout_table

PAGE = REPO / "docs" / "serial.md"


def section(title):
    text = PAGE.read_text()
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end >= 0 else None]


def test_the_ttimeout_table_is_the_generated_one():
    text = section("Sizing tTimeout on a serial link")
    rows = [ln for ln in text.splitlines() if ln.startswith("|")]
    assert "\n".join(rows) + "\n" == timeout_table(), \
        "docs/serial.md's tTimeout table is stale: `.venv/bin/python -m mipprobe.sizing` prints it"


def test_the_123_register_column_is_the_demos_rule():
    """plc/demo.py and mip-cosim add cli.link_timeout_ms: 8 x 270 x 11 / baud s; the table's
    123-register column is that, rounded up to 10 ms, where the gap is 3.5 characters, and up to
    24 ms more above 19,200 baud (the page says so)"""
    above = []
    for baud in (9600, 19200, 38400, 57600, 115200):
        ours, demo = link_timeout_ms(baud, 123), demo_link_timeout_ms(baud)
        if baud <= 19200:
            assert ours == math.ceil(demo / 10) * 10, baud
        else:
            above.append(ours - demo)
    assert max(above) == 24 and min(above) > 0
    assert "up to 24 ms lower" in section("Sizing tTimeout on a serial link")


def test_what_a_line_costs_is_the_same_arithmetic():
    text = section("What a line costs")
    rows = {}
    for ln in text.splitlines():
        m = re.match(r"\| (.+?) \| (\d+) \+ (\d+) \| (\d+) ms \| (\d+) ms \| (\d+) ms \|$", ln)
        if m:
            rows[m.group(1)] = [int(g) for g in m.groups()[1:]]
    assert len(rows) == 4, rows
    for what, (req, rsp, *ms) in rows.items():
        for baud, shown in zip((9600, 19200, 115200), ms):
            assert math.floor(exchange_s(baud, req, rsp) * 1000 + 0.5 + 1e-9) == shown, (what, baud)


def test_the_tables_ttimeout_ends_needless_retransmissions():
    """The page's measurement: 4 records of 123 registers at 9,600 baud, lossless: with a TCP
    tTimeout of 0.3 s every record goes twice, with the table's 2,480 ms more none does."""
    from mipcosim.sim import SEC, LoggerLink, Setup
    out = []
    for extra in (0, link_timeout_ms(9600, 123)):
        st = Setup(link_baud=9600, timeout_ms=300 + extra, records=4, payload=123,
                   status_first=L.RTU_STATUS_FIRST)
        with LoggerLink(st, Path(tempfile.mkdtemp(prefix="ttimeout-"))) as ch:
            assert ch.run_to_end(300 * SEC)
            out.append((ch.plcs[("out", 1)][f"%MW{L.peer_base(1) + L.S_RETRANS}"],
                        ch.plcs[("cen", 0)][f"%MW{L.peer_base(1) + L.R_DUP}"]))
    assert out == [(4, 4), (0, 0)]
    text = section("Sizing tTimeout on a serial link")
    assert "(4\nretransmissions, 4 duplicates discarded at the central); with 0.3 s + 2,480 ms none" in text
