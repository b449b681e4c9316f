"""What the vendor families' tests share: a transfer of the example programs with a family's
glue and stand-ins (mipcosim/vendor_glue.py) in co-simulation, and the record-for-record check."""
from pathlib import Path

from mipcosim import vendor_glue as glue
from mipcosim.check import check, summary
from mipcosim.sim import SEC, LoggerLink, Setup


def sources(family, workdir, glue_text=None, roles=("outstation", "central")):
    """The build's files of the roles with the family's glue (the others run the example
    program as it is); glue_text: the outstation's glue replaced by this text (an integrator's
    mistake)."""
    src = {r: glue.sources(family, r, Path(workdir) / "src") for r in roles}
    if glue_text is not None:
        path = Path(workdir) / "src" / ("mistaken.scl" if family == "s7" else f"mistaken.{family}.st")
        path.write_text(glue_text)
        src["outstation"][-2] = str(path)
    return src


def run(family, workdir, loss, restart, records=24, per_transfer=7, seed=7,
        roles=("outstation", "central"), **setup):
    """roles: the sides whose program has the glue (the quick tier: the outstation only, so its
    central is the example program the chain tests build too); setup: more Setup fields (radio,
    timeout_ms)."""
    st = Setup(loss=loss, seed=seed, records=records, per_transfer=per_transfer, log_period_ms=50,
               sources=sources(family, workdir, roles=roles), channel=tuple(roles), **setup)
    with LoggerLink(st, workdir) as ch:
        if restart != "none":
            ch.run_for(SEC)          # mid read-out
            ch.restart(("out", 1) if restart == "outstation" else ("cen", 0))
        finished = ch.run_to_end(600 * SEC)
        reps = check(ch)
        requests = ch.plcs[("out", 1)].device_stats()["trm"]["requests"]
        return ch, finished, reps, summary(reps), requests


def assert_exact(ch, finished, reps, tot, restart, records=24):
    problems = [p for r in reps for p in r.problems]
    assert finished, f"not all records read out after {ch.now / SEC:.0f} s: {tot} {problems}"
    assert problems == []
    assert tot["lost"] == 0
    for r in reps:
        assert r.records >= records, (r.name, r.records)
    if restart == "none":
        assert tot["duplicated"] == 0 and tot["failed_reported"] == 0
        assert tot["records"] == records


def run_outstation(family, workdir, src, seconds, words, extra=()):
    """The chain with `src`, the outstation's parameter words set first (%MWn: value; a name:
    the outstation's variable OUTSTATION.<name>); the
    outstation's logger counters and the variables `extra` (OUTSTATION.<name>) after `seconds`
    of virtual time, read while the PLC is still there."""
    st = Setup(seed=7, records=24, per_transfer=7, log_period_ms=50, timeout_ms=300,
               sources=src, channel=tuple(src))
    with LoggerLink(st, workdir) as ch:
        for n, v in words.items():
            ch.plcs[("out", 1)][f"OUTSTATION.{n}" if isinstance(n, str) else f"%MW{n}"] = v
        ch.run_for(seconds * SEC)
        o = ch.plcs[("out", 1)]
        return {n: o[f"OUTSTATION.{n}"] for n in
                ("APP.SRC.UTRANSFERSFAILED", "APP.SRC.UTRANSFERSDONE", "APP.SRC.WLASTERROR", *extra)}
