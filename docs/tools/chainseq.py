"""One relay event's trip to the control system as a sequence diagram (docs/chain.md).

    .venv/bin/python docs/tools/chainseq.py trace OUT.jsonl     # run the chain, write the trace
    .venv/bin/python docs/tools/chainseq.py draw TRACE.jsonl -o OUT.svg

`trace` runs the whole chain in the co-simulation (cosim/mipcosim/chain.py: the relay, both
PLCs, the realistic radio 9600 bit/s, the SCADA polling every 50 ms) with one scripted relay
event and writes what happened to it, in order, one JSON line a step: {"t": ns, "from": lane,
"to": lane, "label": ...} for a message, {"t": ns, "note": lane, "label": ...} for a note. The
steps come from the emulator's trace (the PLCs' writes into their modems, the radio telegrams
that carry a block) and from the state the chain shows between two 1 ms steps (the relay's
counters, the programs' status words, the SCADA's store). `draw` renders such a trace; the same
trace gives the same bytes.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from xml.sax.saxutils import escape

from mipcosim.trace import read_trace

REPO = Path(__file__).resolve().parents[2]
LANES = ["relay", "outstation", "trm", "mdp", "central", "scada"]
TITLES = {"relay": "relay (SIPROTEC)", "outstation": "outstation PLC", "trm": "TRM-810",
          "mdp": "MDP-810", "central": "central PLC", "scada": "SCADA"}
W = 1040
X0 = 150
DX = 170
ROW = 24
TOP = 70
FONT = "DejaVu Sans, Verdana, Arial, sans-serif"
EVENT = [0x0102, 101, 0x0101, 1]     # type 1 bit 2, register 101, cause 1 / type 1, value 1


class ChainSeqError(Exception):
    pass


def make_trace(workdir):
    from mipcosim import chain as C
    from mipcosim.sim import MS, Radio
    workdir = Path(workdir)
    emu = workdir / "emulator-trace.jsonl"
    st = C.ChainSetup(events=[(0.5, EVENT)], radio=Radio.realistic(),
                      params=C.SoeParams(timeout_ms=3000, retain=True))
    steps = []

    def add(t, **kw):
        steps.append(dict(t=t, **kw))

    with C.SoeChain(st, workdir, trace=emu) as ch:
        prev = None
        while ch.now < 3000 * MS:
            ch.run_for(MS)
            rs = ch.relay.stats()
            cur = (rs["generated"], rs["acknowledged"], ch.mw32("out", C.OUT_STORED),
                   ch.mw32("out", C.OUT_SENT), ch.mw32("cen", C.CEN_RECORDS),
                   ch.mw32("cen", C.CEN_PUT), len(ch.rows), ch.mw32("cen", C.CEN_ACKED))
            if prev is None:
                prev = cur
                continue
            t = ch.now
            if cur[0] > prev[0]:
                add(t, note="relay", label=f"event recorded: value {EVENT[3]}, time stamp "
                                           f"{C.ORIGIN_MS + 500} ms")
            if cur[2] > prev[2]:
                add(t, **{"from": "relay", "to": "outstation"},
                    label="FC3 40601..40626: 1 entry, SOE_Control = seq + 1*256")
                add(t, note="outstation", label="MIP_SoeReader -> PLC_SoeLog: stored (RETAIN)")
            if cur[1] > prev[1]:
                add(t, **{"from": "outstation", "to": "relay"},
                    label="FC16 SOE_Control := seq + 1*256 (stored; number 1: read again first)")
                add(t, note="relay", label="entry deleted, sequence number raised")
            if cur[4] > prev[4]:
                add(t, **{"from": "mdp", "to": "central"}, label="FC3: record 1 (1 entry)")
                add(t, note="central", label="MIP_Receiver delivers it (xAckByCaller): not acknowledged yet")
            if cur[5] > prev[5]:
                add(t, note="central", label="PLC_SoeHandOver -> MIP_SoeServer: entry offered")
            if cur[6] > prev[6]:
                r = ch.rows[-1]
                add(t, **{"from": "central", "to": "scada"},
                    label=f"FC3 600..625: SOE_Control = {r['seq']} + 1*256, the entry")
                add(t, note="scada", label=f"stored: value {r['value']}, time stamp {r['ts_ms']} ms")
                add(t, **{"from": "scada", "to": "central"},
                    label=f"FC6 SOE_Control := {r['seq']} + 1*256")
            if cur[7] > prev[7]:
                add(t, note="central", label="MIP_SoeServer: acknowledged -> record processed")
            if cur[3] > prev[3]:
                add(t, **{"from": "trm", "to": "outstation"}, label="FC3: acknowledgement 16#FFFF")
                add(t, note="outstation", label="transfer done: the entry leaves the logger")
            prev = cur
        left = ch.relay.stats()["entries"]
        if len(ch.rows) != 1 or left:
            raise ChainSeqError(f"the event did not make the trip: {len(ch.rows)} taken, {left} left")
    for ev in read_trace(emu):
        if ev["ev"] == "modbus" and ev["fc"] == 16 and ev.get("exc") == 0 and ev["t"] > 100_000_000:
            plc, modem = ("outstation", "trm") if ev["ep"] == "trm" else ("central", "mdp")
            what = ("record 16#FFFF (end of transfer)" if ev["w0"] == 0xFFFF and ev["ep"] == "trm"
                    else f"record {ev['w0']} ({ev['wq'] - 1} registers)" if ev["ep"] == "trm"
                    else f"acknowledge {'16#FFFF' if ev['w0'] == 0xFFFF else ev['w0']}")
            add(ev["t"], **{"from": plc, "to": modem}, label=f"FC16: {what}")
        elif ev["ev"] == "radio" and ev["regs"] > 0 and ev["t"] > 100_000_000:
            a, b = ("trm", "mdp") if ev["dir"] == "up" else ("mdp", "trm")
            what = ("record" if ev["dir"] == "up" else "acknowledgement")
            num = "16#FFFF" if ev.get("r0") == 0xFFFF else ev.get("r0")
            add(ev["t"], **{"from": a, "to": b},
                label=f"radio: {what} {num} ({ev['bytes']} bytes){' LOST' if ev['lost'] else ''}")
    steps.sort(key=lambda s: s["t"])      # stable: notes stay after their message
    return steps


def draw(steps, title):
    for n, s in enumerate(steps, 1):
        lanes = [s.get("note")] if "note" in s else [s.get("from"), s.get("to")]
        if not isinstance(s.get("t"), int) or not isinstance(s.get("label"), str) or \
                any(x not in LANES for x in lanes):
            raise ChainSeqError(f"step {n}: needs t (ns), label and lanes of {', '.join(LANES)}")
    x = {lane: X0 + DX * i for i, lane in enumerate(LANES)}
    h = TOP + ROW * (len(steps) + 1) + 30
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" '
           f'viewBox="0 0 {W} {h}" font-family="{FONT}" font-size="11">',
           '<defs><marker id="a" markerWidth="8" markerHeight="8" refX="7" refY="4" '
           'orient="auto"><path d="M0,0 L8,4 L0,8 z" fill="#1f5f99"/></marker></defs>',
           f'<rect width="{W}" height="{h}" fill="white"/>',
           f'<text x="{W // 2}" y="20" text-anchor="middle" font-size="14" '
           f'font-weight="bold">{escape(title)}</text>']
    for lane in LANES:
        out.append(f'<text x="{x[lane]}" y="{TOP - 18}" text-anchor="middle" '
                   f'font-weight="bold">{escape(TITLES[lane])}</text>')
        out.append(f'<line x1="{x[lane]}" y1="{TOP - 10}" x2="{x[lane]}" y2="{h - 20}" '
                   f'stroke="#7f8c8d" stroke-dasharray="4,3"/>')
    out.append(f'<text x="8" y="{TOP - 18}" font-weight="bold">t (ms)</text>')
    for i, s in enumerate(steps):
        y = TOP + ROW * (i + 1)
        out.append(f'<text x="8" y="{y + 4}" fill="#7f8c8d">{s["t"] / 1e6:.0f}</text>')
        if "note" in s:
            cx = x[s["note"]]
            wd = 7 * len(s["label"]) + 12
            left = min(max(cx - wd // 2, 40), W - wd - 4)
            out.append(f'<rect x="{left}" y="{y - 11}" width="{wd}" height="18" rx="3" '
                       f'fill="#e8f6ef" stroke="#1e8449"/>')
            out.append(f'<text x="{left + wd // 2}" y="{y + 2}" text-anchor="middle">'
                       f'{escape(s["label"])}</text>')
        else:
            a, b = x[s["from"]], x[s["to"]]
            red = s["label"].endswith("LOST")
            col = "#c0392b" if red else "#1f5f99"
            out.append(f'<line x1="{a}" y1="{y}" x2="{b}" y2="{y}" stroke="{col}" '
                       f'stroke-width="1.5" marker-end="url(#a)"/>')
            out.append(f'<text x="{(a + b) // 2}" y="{y - 4}" text-anchor="middle" fill="{col}" '
                       f'stroke="white" stroke-width="3" paint-order="stroke">'
                       f'{escape(s["label"])}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


TITLE = "One relay event's trip to the control system (the pull way)"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="chainseq", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("trace", help="run the chain in the co-simulation, write the trace")
    t.add_argument("out")
    t.add_argument("--workdir", default=None)
    d = sub.add_parser("draw", help="render a trace as SVG")
    d.add_argument("trace")
    d.add_argument("-o", "--out", required=True)
    d.add_argument("--title", default=TITLE)
    a = ap.parse_args(argv)
    try:
        if a.cmd == "trace":
            import tempfile
            wd = a.workdir or tempfile.mkdtemp(prefix="chainseq-")
            steps = make_trace(wd)
            Path(a.out).write_text("".join(json.dumps(s, sort_keys=True) + "\n" for s in steps))
        else:
            steps = []
            for n, line in enumerate(Path(a.trace).read_text().splitlines(), 1):
                try:
                    steps.append(json.loads(line))
                except ValueError:
                    raise ChainSeqError(f"{a.trace}:{n}: not a JSON line") from None
            Path(a.out).write_text(draw(steps, a.title))
    except (ChainSeqError, OSError) as e:
        print(f"chainseq: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
