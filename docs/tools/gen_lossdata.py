"""Throughput of a logger transfer against radio loss, from the co-simulation. Writes
docs/data/throughput-vs-loss.json (draw it with docs/tools/lossplot.py).

    .venv/bin/python docs/tools/gen_lossdata.py [-o FILE] [--records 20] [--seeds 10]
                                                [--source cosim|blocks]

--source cosim (default): the whole chain of cosim/ in one process, in virtual time: the
example programs plc/outstation.st and plc/central.st (st_lib's MIP_Sender / MIP_Receiver with
the logger and the record store) in the soft-PLC runtime with its Modbus master, against the
emulator core, with the realistic radio (9600 bit/s, 20 ms gaps).
--source blocks: the st_lib blocks alone in two soft PLCs (docs/tools/chainsim.py: the same
kernel and runtime, the program docs/tools/chain_main.st reads every 100 ms).

For each loss probability p (both directions, independent losses) and each drive
(spontaneous, polled) one transfer of `records` records of 122 payload registers is run per
seed; the figure is payload registers per second of virtual time from the start of the first
radio telegram carrying record 1 to the end of the transfer (the sender's start-up (reset record, wait)
after a PLC start happens once, not per transfer, and is not counted).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from mipcosim.kernel import MS
from mipcosim.trace import parse
from stc import oneline

REPO = Path(__file__).resolve().parents[2]
LOSSES = [0.0, 0.05, 0.1, 0.2, 0.3, 0.4]
PAYLOAD = 122
LIMIT_S = 300          # a 20-record transfer takes well under 30 s; after 300 s it is stuck


class DataError(RuntimeError):
    pass


def first_record_start(trace_lines):
    for d in parse(trace_lines):
        if d.get("ev") == "radio" and d.get("dir") == "up" and d.get("regs") \
                and d.get("r0") == 1:
            return d["t0"]
    raise DataError("no radio telegram carried record 1")


def run_cosim(p, drive, seed, records, workdir):
    from mipcosim import programs
    from mipcosim.sim import LoggerLink, CosimError, Radio, Setup
    if os.environ.get("MIP_STLIB_DIR"):          # as in chainsim: st_lib from elsewhere
        programs.ST_LIB = Path(os.environ["MIP_STLIB_DIR"])
    st = Setup(loss=p, seed=seed, records=records, payload=PAYLOAD, timeout_ms=1500,
               polled=drive == "polled", radio=Radio.realistic())
    with tempfile.TemporaryDirectory() as tmp:
        trace = Path(tmp) / "t.jsonl"
        try:
            with LoggerLink(st, workdir, trace=trace) as ch:
                ok = ch.run_to_end(LIMIT_S * 1000 * MS, step_ns=10 * MS, settle_ns=0)
                t_end = ch.now
        except CosimError as e:
            raise DataError(f"cosim: {e}") from None
        if not ok:
            return None
        t0 = first_record_start(trace.read_text().splitlines())
    return records * PAYLOAD / ((t_end - t0) / 1e9)



def run_blocks(p, drive, seed, records, workdir=None):
    from mipdocs.chainsim import LoggerLink, ChainError, Side
    from mipdocs.gen_traces import WORK, logger_data
    polled = drive == "polled"
    data = logger_data(records * PAYLOAD, seed)
    o = Side("outstation", "sender", data=data, polled=polled, timeout_ms=1500, read_ms=100)
    c = Side("central", "receiver", polled=polled, timeout_ms=1500, read_ms=100,
             read_phase_ms=50)
    try:
        ch = LoggerLink(WORK, o, c, loss_up=p, loss_down=p, seed=seed)
    except ChainError as e:
        raise DataError(str(e)) from None
    ok = ch.run_until(lambda: o.send_done, LIMIT_S * 1000)
    t_end = ch.t
    lines = ch.trace()
    ch.close()
    if not ok:
        return None
    if c.transfers != [data]:
        raise DataError(f"p={p} {drive} seed={seed}: the data arrived wrong")
    return len(data) / ((t_end - first_record_start(lines)) / 1e9)


SOURCES = {
    "cosim": (run_cosim, "cosim/ (plc/outstation.st + plc/central.st in the soft-PLC runtime "
                         "with its Modbus master, emulator core), virtual time",
              "10 ms scan, tTimeout 1.5 s (the example programs' wiring)"),
    "blocks": (run_blocks, "st_lib MIP_Sender/MIP_Receiver in the soft-PLC runtime with its "
                           "Modbus master (docs/tools/chain_main.st), emulator core, virtual time",
               "10 ms scan, read every 100 ms, tTimeout 1.5 s"),
}


def run(p, drive, seed, records, source="cosim"):
    """Payload registers per second, or None when the transfer did not finish in LIMIT_S."""
    fn = SOURCES[source][0]
    work = os.environ.get("MIP_DOCS_WORKDIR")       # as gen_traces.WORK
    return fn(p, drive, seed, records, Path(work) / "cosim" if work else REPO / "build" / "docs" / "cosim")


def main(argv=None):
    ap = argparse.ArgumentParser(prog="gen_lossdata",
                                 description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("-o", "--output", default=str(REPO / "docs" / "data" / "throughput-vs-loss.json"))
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--source", choices=sorted(SOURCES), default="cosim")
    a = ap.parse_args(argv)
    series = {}
    for drive in ("spontaneous", "polled"):
        pts = []
        for p in LOSSES:
            rates, unfinished = [], []
            for seed in range(1, a.seeds + 1):
                try:
                    r = run(p, drive, seed, a.records, a.source)
                except DataError as e:
                    print(f"gen_lossdata: error: {e}", file=sys.stderr)
                    return 1
                if r is None:
                    unfinished.append(seed)
                else:
                    rates.append(round(r, 1))
            pts.append({"loss": p, "regs_per_s": rates, "unfinished_seeds": unfinished})
            more = f", NOT finished in {LIMIT_S} s: seeds {unfinished}" if unfinished else ""
            print(f"gen_lossdata: {drive} p={p}: {rates} registers/s{more}", flush=True)
        series[drive] = pts
    _, source, plc = SOURCES[a.source]
    out = {"source": source, "source_key": a.source, "records": a.records,
           "payload_per_record": PAYLOAD, "seeds": a.seeds,
           "radio": "9600 bit/s, 20 ms gap, 12 bytes overhead, independent losses up = down",
           "plc": plc, "measured": "first telegram of record 1 to the end of the transfer",
           "limit_s": LIMIT_S,
           "series": series}
    return oneline.write_output("gen_lossdata", a.output, json.dumps(out, indent=1) + "\n",
                                make_dir=True)


if __name__ == "__main__":
    sys.exit(main())
