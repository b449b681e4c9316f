"""Renders the sequence diagrams of the guide from the checked-in traces in docs/traces/.

    .venv/bin/python docs/tools/mkdiagrams.py [--outdir docs/img]

The list below is the one place that names each diagram, its trace, title and caption.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mipdocs import seqdiag

REPO = Path(__file__).resolve().parents[2]
COMMON = ("st_lib blocks in two soft PLCs (plcrt, its Modbus master does the requests) + "
          "emulator core in the co-simulation kernel, virtual time (docs/tools/gen_traces.py); "
          "empty polls/answers and reads without new data omitted.")
DIAGRAMS = [
    ("note-2-1-1", "Note 2.1.1: five records, polled by the central, record 2 lost on the radio",
     "Trace docs/traces/note-2-1-1.jsonl (uplink loss 20 %, bursts of 4, seed found by the "
     "generator). " + COMMON),
    ("bidirectional", "Note 2.2: both sides send at once (MIP_Link on both sides)",
     "Trace docs/traces/bidirectional.jsonl (no loss). Blocks are [outstation stream | central "
     "stream]. " + COMMON),
    ("restart", "Restart: the outstation PLC restarts in the middle of a transfer",
     "Trace docs/traces/restart.jsonl (no loss, spontaneous drive). " + COMMON),
    ("static-openplc", "Static mode with OpenPLC-style cyclic I/O: only changed blocks go on air",
     "Trace docs/traces/static-openplc.jsonl (static mode, 40 registers; the runtime's cyclic "
     "policy reads and writes each PLC's whole ranges every 500 ms, the first write before the "
     "program ran; a write counts done after 750 ms; no loss). " + COMMON),
    ("pipelined", "Window 2: the next record goes up while the one before waits for its ack",
     "Trace docs/traces/pipelined.jsonl (MIP_Sender.uWindow = 2, spontaneous drive, no loss; "
     "both PLCs read every 100 ms). " + COMMON),
    ("pipelined-slow-central",
     "Window 2 with a slow central: a record overwritten, the sender goes back to stop and wait",
     "Trace docs/traces/pipelined-slow-central.jsonl (MIP_Sender.uWindow = 2, tTimeout 1.5 s, "
     "spontaneous drive, no loss; the central's PLC reads every 600 ms, the outstation's every "
     "100 ms). " + COMMON),
]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="mkdiagrams", description=__doc__.splitlines()[0])
    ap.add_argument("--tracedir", default=str(REPO / "docs" / "traces"))
    ap.add_argument("--outdir", default=str(REPO / "docs" / "img"))
    a = ap.parse_args(argv)
    Path(a.outdir).mkdir(parents=True, exist_ok=True)
    rc = 0
    for name, title, caption in DIAGRAMS:
        rc |= seqdiag.main([str(Path(a.tracedir) / f"{name}.jsonl"), "-o",
                            str(Path(a.outdir) / f"seq-{name}.svg"), "--title", title,
                            "--caption", caption])
    return rc


if __name__ == "__main__":
    sys.exit(main())
