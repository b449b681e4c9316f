"""Throughput of the st_lib blocks against radio loss: st_lib in two soft PLCs, the emulator
core, virtual time (docs/tools/chainsim.py). Writes docs/data/throughput-vs-loss.json.

    .venv/bin/python docs/tools/gen_lossdata.py [-o FILE] [--records 20] [--seeds 5]

For each loss probability p (the same on the downlink and the uplink, independent losses) and
each drive (spontaneous, polled), one transfer of `records` full records (122 payload
registers each) is run per seed; the figure is payload registers per second of virtual time,
from the first write of record 1 to xDone (the sender's start-up quiet time of tTimeout after
a PLC start is not counted: it happens once, not per transfer). Radio: the emulator's defaults (9600 bit/s, 20 ms
gaps, 12 bytes overhead). PLC: 10 ms scan, a read every 100 ms, tTimeout 1.5 s.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from chainsim import MS, Chain, ChainError, Side  # noqa: E402
from mipemu_ctypes import EmuError  # noqa: E402
from gen_traces import WORK, logger_data  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
LOSSES = [0.0, 0.05, 0.1, 0.2, 0.3, 0.4]


def run(p, drive, seed, records):
    polled = drive == "polled"
    data = logger_data(records * 122, seed)
    o = Side("outstation", "sender", data=data, polled=polled, timeout_ms=1500, read_ms=100)
    c = Side("central", "receiver", polled=polled, timeout_ms=1500, read_ms=100,
             read_phase_ms=50)
    ch = Chain(WORK, o, c, loss_up=p, loss_down=p, seed=seed)
    ok = ch.run_until(lambda: o.send_done, 600_000)
    # from the first write of record 1 (after the sender's start-up quiet time) to xDone
    t0 = next((d["t"] for _, d in ch.plc_lines if d["side"] == "outstation"
               and d["what"] == "write" and d["value"] == [1]), 0)
    t = ch.t - t0
    stats = ch.net.stats(1)
    ch.close()
    if not ok or c.transfers != [data]:
        raise SystemExit(f"gen_lossdata: error: p={p} {drive} seed={seed}: transfer incomplete "
                         f"or wrong")
    return len(data) / (t / 1e9), stats


def main(argv=None):
    ap = argparse.ArgumentParser(prog="gen_lossdata", description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default=str(REPO / "docs" / "data" / "throughput-vs-loss.json"))
    ap.add_argument("--records", type=int, default=20)
    ap.add_argument("--seeds", type=int, default=5)
    a = ap.parse_args(argv)
    series = {}
    for drive in ("spontaneous", "polled"):
        pts = []
        for p in LOSSES:
            rates = []
            for seed in range(1, a.seeds + 1):
                try:
                    r, _ = run(p, drive, seed, a.records)
                except (ChainError, EmuError) as e:
                    print(f"gen_lossdata: error: {e}", file=sys.stderr)
                    return 1
                rates.append(round(r, 1))
            pts.append({"loss": p, "regs_per_s": rates})
            print(f"gen_lossdata: {drive} p={p}: {rates} registers/s", flush=True)
        series[drive] = pts
    out = {"source": "st_lib MIP_Sender/MIP_Receiver in plcharness + emulator core, virtual time",
           "records": a.records, "payload_per_record": 122, "seeds": a.seeds,
           "radio": "9600 bit/s, 20 ms gap, 12 bytes overhead, independent losses up = down",
           "plc": "10 ms scan, read every 100 ms, tTimeout 1.5 s",
           "measured": "first write of record 1 to xDone", "series": series}
    Path(a.output).parent.mkdir(parents=True, exist_ok=True)
    Path(a.output).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
