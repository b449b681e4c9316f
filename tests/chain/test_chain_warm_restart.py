"""Warm restarts in co-simulation (LoggerLink.restart(who, warm=True)): a PLC comes back with the
RETAIN variables of its last complete snapshot - the kill -9 semantics of plcrt, so everything
since that snapshot is rolled back; a cold restart resets them (docs/retain.md)."""
from pathlib import Path

import pytest

from mipcosim import programs as L
from mipcosim.check import check, summary
from mipcosim.sim import SEC, LoggerLink, Setup

if not (Path(__file__).resolve().parents[2] / "build" / "cosim" / "libmipcosim.so").is_file():
    pytest.fail("build/cosim/libmipcosim.so not built: run make first", pytrace=False)

EVERY = 37   # the probe asks for a snapshot every 37 scans (more often than the 1 s period)

# A second program in the outstation's resource: a retained scan counter that uses the
# durability handshake at the addresses of L.RETAIN_REQUEST / L.RETAIN_SAVED.
PROBE = f"""
PROGRAM RetainProbe
VAR RETAIN n : UDINT; END_VAR
VAR req AT {L.RETAIN_REQUEST} : BOOL; saved AT {L.RETAIN_SAVED} : WORD; END_VAR
VAR seen : WORD; END_VAR
n := n + 1;
seen := saved;
req := (n MOD {EVERY}) = 0;
END_PROGRAM
"""


@pytest.fixture(scope="module")
def probe_sources(tmp_path_factory):
    d = tmp_path_factory.mktemp("probe")
    srcs = L.program_sources("outstation", False)
    text = Path(srcs[-1]).read_text()
    line = "PROGRAM out0 WITH tMain : Outstation;"
    assert text.count(line) == 1, "plc/outstation.st: the resource's program line changed"
    # the outstation's own handshake (its blocks' gate, off here) moves to unused addresses,
    # so that the probe alone drives the runtime's
    for own, free in (("snapReq AT %QX8.0", "snapReq AT %QX9.0"), ("snapSaved AT %IW8", "snapSaved AT %IW9")):
        assert text.count(own) == 1, f"plc/outstation.st: {own} changed"
        text = text.replace(own, free)
    (d / "probe.st").write_text(PROBE)
    (d / "outstation.st").write_text(text.replace(line, line + "\n    PROGRAM probe0 WITH tMain : RetainProbe;"))
    return srcs[:-1] + [str(d / "probe.st"), str(d / "outstation.st")]


@pytest.fixture(scope="module")
def plain_central(tmp_path_factory):
    """plc/central.st without RETAIN: a program that retains nothing."""
    d = tmp_path_factory.mktemp("plain")
    srcs = L.program_sources("central", False)
    text = Path(srcs[-1]).read_text()
    assert text.count("VAR RETAIN\n") == 1, "plc/central.st: its RETAIN block changed"
    (d / "central.st").write_text(text.replace("VAR RETAIN\n", "VAR\n"))
    return srcs[:-1] + [str(d / "central.st")]


def chain(workdir, sources, central=None):
    srcs = {"outstation": sources}
    if central:
        srcs["central"] = central
    return LoggerLink(Setup(records=24, per_transfer=7, log_period_ms=50, loss=0.1, seed=3,
                       sources=srcs), workdir)


def test_warm_restart_rolls_back_to_the_last_snapshot_cold_restart_resets(chain_workdir, probe_sources,
                                                                         plain_central):
    out = ("out", 1)
    with chain(chain_workdir, probe_sources, plain_central) as ch:
        ch.run_until(2500 * 1_000_000)
        plc = ch.plcs[out]
        n = plc["probe0.n"]
        assert n >= 240
        # requested snapshots at n = 37, 74, ...; the program saw each one in the next scan
        assert plc.retain_saves == n // EVERY
        assert plc["probe0.seen"] == (n - 1) // EVERY
        ch.restart(out, warm=True)
        warm = ch.plcs[out]
        assert warm is not plc
        assert warm["probe0.n"] == EVERY * (n // EVERY) < n    # rolled back to the snapshot
        assert ch.retain_stats()["warm_restarts"] == 1 and ch.retain_stats()["restored"] == 1
        snap = EVERY * (n // EVERY)
        ch.run_for(SEC)
        assert warm["probe0.n"] == snap + 100                  # and goes on from there
        # its own count from 0: the requests of the 100 scans since the restart
        assert warm.retain_saves == (snap + 100) // EVERY - snap // EVERY
        ch.restart(out)                                         # cold
        assert ch.plcs[out]["probe0.n"] == 0
        # the central has no RETAIN variables: a warm restart of it is a cold one
        ch.restart(("cen", 0), warm=True)
        stats = ch.retain_stats()
        assert stats["warm_restarts"] == 2 and stats["restored"] == 1
        assert stats["snapshots"] >= n // EVERY + 100 // EVERY
        assert ch.run_to_end(900 * SEC)
        reps = check(ch)
        assert [p for r in reps for p in r.problems] == [] and summary(reps)["lost"] == 0


def test_without_a_snapshot_yet_a_warm_restart_is_cold(chain_workdir, probe_sources):
    with chain(chain_workdir, probe_sources) as ch:
        ch.run_until(200 * 1_000_000)        # 20 scans: before the first request and period
        assert ch.plcs[("out", 1)].retain_saves == 0
        ch.restart(("out", 1), warm=True)
        assert ch.plcs[("out", 1)]["probe0.n"] == 0
        stats = ch.retain_stats()
        assert (stats["warm_restarts"], stats["restored"]) == (1, 0)
