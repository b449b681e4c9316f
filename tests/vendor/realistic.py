"""The glue of a family over the realistic radio (9,600 bit/s, 20 ms slot gaps, 30 % loss) with
the PLC-to-modem line a Modbus RTU segment at 9,600 bit/s (a 125-register read takes about
0.3 s on it, in virtual time), the issue-47 condition a vendor block's reply timeout must
survive."""
from pathlib import Path

from mipcosim.check import check, summary
from mipcosim.sim import SEC, LoggerLink, Radio, Setup

RECORDS = 8


def setup(src, roles, loss=0.3, seed=7, link_baud=9600):
    return Setup(loss=loss, seed=seed, records=RECORDS, per_transfer=4, log_period_ms=50,
                 timeout_ms=3000, radio=Radio.realistic(), link_baud=link_baud, sources=src,
                 channel=tuple(roles))


def run_to_end(src, roles, workdir, limit_s=900):
    """(finished, virtual seconds, summary, problems) of a read-out of RECORDS records."""
    with LoggerLink(setup(src, roles), Path(workdir)) as ch:
        finished = ch.run_to_end(limit_s * SEC)
        reps = check(ch)
        return finished, ch.now / SEC, summary(reps), [p for r in reps for p in r.problems]


def run_for(src, roles, workdir, seconds, names):
    """The variables `names` ("OUTSTATION.X" / "CENTRAL.X") after `seconds` of virtual time."""
    with LoggerLink(setup(src, roles), Path(workdir)) as ch:
        ch.run_for(seconds * SEC)
        plc = {"OUTSTATION": ch.plcs[("out", 1)], "CENTRAL": ch.plcs[("cen", 0)]}
        return {n: plc[n.split(".", 1)[0]][n] for n in names}
