"""Sequence diagram (SVG) of one station's traffic from a mip-emulator JSON-lines trace.

    .venv/bin/python docs/tools/seqdiag.py TRACE.jsonl -o OUT.svg [--title T] [--station 1]
                                           [--from-ms A] [--to-ms B]

Four lifelines: outstation PLC, TRM-810, MDP-810, central PLC. Shown:
- Modbus writes (FC16/FC23) of a PLC into its modem, and rejected requests (exception);
- radio telegrams that carry a block, that confirm one (an answer confirming the poll's block,
  the MDP's ack), and every lost telegram (red, ending in a cross);
- "station" lines of the emulator (unreachable / reachable);
- lines with "ev":"plc" if the trace has them (added by docs/tools/chainsim.py: what the PLC
  read, delivered, ignored, finished or failed, a pipelined sender going back; the label of
  its writes).
Marked on top of that: the reset record (record 0, orange: it opens a session, it is not an
idle block), a record a receiving PLC read again after delivering it (the discarded duplicate),
and gaps of JUMP_MS or more between two rows (a break across the lifelines with the time that
passed: rows are evenly spaced, time is not). Notes get rows of their own and arrow labels a
white halo, so nothing covers a label.
Empty polls and answers and the PLCs' Modbus reads are left out (a note with the count of
left-out lines would be noise; the caption says what is omitted). The output depends only on the
trace: the same trace gives the same bytes.
"""
from __future__ import annotations

import argparse
import re
import sys
import textwrap
from xml.sax.saxutils import escape

from mipcosim.trace import TraceError, read_trace
from stc import oneline

W = 980
X_TIME = 62
X = {"outstation": 180, "trm": 410, "mdp": 630, "central": 860}
HEAD_Y = 58
ROW = 22
NOTE_ROW = 28             # a note's row: its box stays clear of the labels above and below
JUMP_MS = 400             # a gap at least this long between two rows is drawn as a break
JUMP_H = 20
ORANGE = "#d35400"
FONT = "DejaVu Sans, Verdana, Arial, sans-serif"
RED = "#c0392b"
GREY = "#7f8c8d"
BLUE = "#1f5f99"
GREEN = "#1e8449"
NOTE_FILL = {"deliver": "#e8f6ef", "done": "#d5f5e3", "error": "#fadbd8", "restart": "#fdebd0",
             "station": "#fdebd0", "duplicate": "#fef5e7", "ignore": "#fef5e7",
             "goback": "#fdebd0"}


def load(path):
    """The events of the trace file `path` ("-": standard input), each with its "_line"."""
    return read_trace(path, line_numbers=True, prog="seqdiag")


def fmt_ms(t_ns):
    return f"{t_ns // 1_000_000} ms"


def writes_by_side(events, station):
    """Accepted writes per side: (t, w0, wq, label), label from the plc line if there is one."""
    labels = {}
    for d in events:
        if d["ev"] == "plc" and d.get("what") == "write":
            labels[(d.get("side"), d["t"])] = d.get("text", "").removeprefix("write ").split(" (")[0]
    out = {"outstation": [], "central": []}
    for d in events:
        if (d["ev"] == "modbus" and d.get("st") == station and d.get("fc") in (6, 16, 23)
                and not d.get("exc") and "close" not in d):
            side = "outstation" if d.get("ep") == "trm" else "central"
            out[side].append((d["t"], d.get("w0"), d.get("wq"), labels.get((side, d["t"]))))
    return out


def block_label(writes, capture_t, r0, regs):
    """What a telegram carries: the last write before the block was taken on air (a write at
    the same instant comes after the radio step), if its first register and length agree."""
    for t, w0, wq, label in reversed(writes):
        if t < capture_t:
            if w0 == r0 and wq == regs and label:
                return label
            break
    return f"[0]={r0}"


def rows_from(events, station, t_from, t_to):
    """The rows to draw: (t, kind, data) in trace order."""
    rows = []
    writes = writes_by_side(events, station)
    last_poll_end = 0
    labels = {(d.get("side"), d["t"]): d.get("text", "") for d in events
              if d["ev"] == "plc" and d.get("what") == "write"}
    for d in events:
        t = d["t"]
        ev = d["ev"]
        in_window = t_from <= t <= t_to
        if ev == "modbus":
            if d.get("st") != station or not in_window:
                continue
            side = "outstation" if d.get("ep") == "trm" else "central"
            fc, exc = d.get("fc"), d.get("exc", 0)
            if "close" in d:
                rows.append((t, "mb_close", {"side": side, "text": f"frame closed: {d['close']}"}))
            elif exc:
                what = f"FC{fc} at {d.get('wa', d.get('ra', '?'))}"
                rows.append((t, "mb_exc", {"side": side, "text": f"{what}: exception {exc:02X}"}))
            elif fc in (6, 16, 23):
                label = labels.get((side, t)) or (
                    f"FC{fc} write, [0]={d.get('w0', '?')} ({plural(d.get('wq', 0))})")
                rows.append((t, "mb_write", {"side": side, "text": label}))
        elif ev == "radio":
            if d.get("st") != station:
                continue
            regs, lost, kind = d.get("regs", 0), d.get("lost", False), d.get("kind")
            down = d.get("dir") == "down"
            capture = d.get("t0", t) if kind == "poll" else last_poll_end
            if kind == "poll":
                last_poll_end = t
            if not in_window:
                continue
            if regs:
                src = "central" if down else "outstation"
                body = block_label(writes[src], capture, d.get("r0"), regs)
                text = f"{kind}: {body} ({plural(regs)})"
            elif kind == "ack":
                text = "ack (link confirms the block)"
            elif kind == "answer" and d.get("ack"):
                text = "answer, confirms the block"
            else:
                text = f"{kind}, empty"
            if not (regs or lost or kind == "ack" or (kind == "answer" and d.get("ack"))):
                continue
            rows.append((t, "radio", {"down": down, "lost": lost, "regs": regs,
                                      "text": text + (": LOST" if lost else "")}))
        elif ev == "station":
            if d.get("st") != station or not in_window:
                continue
            rows.append((t, "note", {"side": "radio", "what": "station",
                                     "text": f"station {station} {d.get('state')}"}))
        elif ev == "plc" and in_window:
            side, what = d.get("side"), d.get("what")
            if side not in X or what == "write":
                continue
            if what == "read":
                rows.append((t, "mb_read", {"side": side, "text": d.get("text", "")}))
            else:
                rows.append((t, "note", {"side": side, "what": what, "text": d.get("text", "")}))
    return mark_duplicates(events, rows)


RESET_RE = re.compile(r"\brecord 0\b")


def mark_reset(text):
    """'record 0' is the reset record that opens a session: say so in the label."""
    return RESET_RE.sub("RESET record 0", text)


def received_record(side, text):
    """The record number a PLC's read shows of the stream it receives (None: none)."""
    m = re.search(r"\brecord (\d+)\b", text)
    if m:
        return int(m.group(1))
    m = re.search(r"\[(\d+) \| (\d+)\]", text)      # bidirectional: [outstation | central]
    if m:
        return int(m.group(1) if side == "central" else m.group(2))
    return None


def mark_duplicates(events, rows):
    """Adds a note after every read in which a PLC sees again a record it already delivered
    (the receiver discards it and acknowledges it again). A reset record (0) or a restart of
    that PLC starts a new session."""
    delivered = {"outstation": set(), "central": set()}
    out = []
    reads = {}
    for d in events:
        if d["ev"] == "plc" and d.get("what") == "deliver":
            reads.setdefault((d.get("side"), d["t"]), []).append("deliver")
    for row in rows:
        out.append(row)
        t, kind, d = row
        side = d.get("side")
        if kind == "note" and d.get("what") == "restart" and side in delivered:
            delivered[side].clear()
        if kind == "note" and d.get("what") == "deliver" and side in delivered:
            n = received_record(side, d["text"])
            if n is not None:
                delivered[side].add(n)
        if kind != "mb_read" or side not in delivered:
            continue
        n = received_record(side, d["text"])
        if n == 0:
            delivered[side].clear()
        elif n is not None and n in delivered[side] and "deliver" not in reads.get((side, t), []):
            out.append((t, "note", {"side": side, "what": "duplicate",
                                    "text": f"record {n} again: discarded (already delivered)"}))
    return out


def plural(n):
    return f"{n} reg" if n == 1 else f"{n} regs"


def text_el(x, y, s, anchor="middle", size=12, fill="#222", weight=None, italic=False,
            halo=False):
    attrs = f'x="{x}" y="{y}" text-anchor="{anchor}" font-size="{size}" fill="{fill}"'
    if halo:
        attrs += ' stroke="#ffffff" stroke-width="3" stroke-linejoin="round" paint-order="stroke"'
    if weight:
        attrs += f' font-weight="{weight}"'
    if italic:
        attrs += ' font-style="italic"'
    return f"<text {attrs}>{escape(s)}</text>"


def arrow(x1, x2, y, color, dashed=False, lost=False, width=1.4):
    out = []
    dash = ' stroke-dasharray="6,4"' if dashed else ""
    if lost:
        xm = x1 + (x2 - x1) * 3 // 4
        out.append(f'<line x1="{x1}" y1="{y}" x2="{xm}" y2="{y}" stroke="{color}" '
                   f'stroke-width="{width}"{dash}/>')
        out.append(f'<path d="M{xm - 5},{y - 5} L{xm + 5},{y + 5} M{xm - 5},{y + 5} '
                   f'L{xm + 5},{y - 5}" stroke="{color}" stroke-width="2.2"/>')
        return out
    out.append(f'<line x1="{x1}" y1="{y}" x2="{x2}" y2="{y}" stroke="{color}" '
               f'stroke-width="{width}"{dash}/>')
    s = 1 if x2 > x1 else -1
    out.append(f'<path d="M{x2},{y} L{x2 - 9 * s},{y - 4} L{x2 - 9 * s},{y + 4} Z" '
               f'fill="{color}"/>')
    return out


def note(xc, y, s, fill, width=None):
    w = width or max(80, 7 * len(s) + 14)
    x = min(max(xc - w // 2, X_TIME + 4), W - 6 - w)
    return [f'<rect x="{x}" y="{y - 8}" width="{w}" height="16" rx="4" fill="{fill}" '
            f'stroke="#999" stroke-width="0.8"/>', text_el(x + w // 2, y + 4, s, size=11)]


def layout(rows):
    """y of every row and the time breaks [(y, gap_ns)]; returns (ys, breaks, height of rows)."""
    ys, breaks, y, last_t = [], [], 0, None
    for t, kind, _ in rows:
        if last_t is not None and t - last_t >= JUMP_MS * 1_000_000:
            # the difference of the row times as printed (whole ms)
            breaks.append((y + JUMP_H // 2, (t // 1_000_000 - last_t // 1_000_000) * 1_000_000))
            y += JUMP_H
        h = NOTE_ROW if kind == "note" else ROW
        ys.append(y + (h // 2 + 2 if kind == "note" else 12))
        y += h
        last_t = t
    return ys, breaks, max(y, ROW)


def fmt_gap(ns):
    ms = ns // 1_000_000
    return f"+{ms / 1000:.1f} s" if ms >= 10_000 else f"+{ms} ms"


def time_margin(rows, breaks):
    """Extra width left of the diagram for time labels longer than the time column (a run of
    more than about 100 s: "1795111 ms"); 0 for the usual ones, so their SVG stays the same.
    Width of a 10 px label: at most 0.65 em per character (DejaVu Sans: m 0.97, digits 0.64)."""
    labels = [fmt_ms(t) for t, _, _ in rows] + [fmt_gap(g) for _, g in breaks]
    need = max((0.65 * 10 * len(l) for l in labels), default=0)
    return max(0, int(need - (X_TIME - 8)) + 4) if need > X_TIME - 8 else 0


def render(rows, title, caption):
    top = HEAD_Y + 34
    ys, breaks, rows_h = layout(rows)
    h = top + rows_h + 36 + 13 * len(textwrap.wrap(caption, 150))
    left = time_margin(rows, breaks)
    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W + left}" height="{h}" '
         f'viewBox="{-left} 0 {W + left} {h}" font-family="{FONT}">',
         f'<rect x="{-left}" y="0" width="{W + left}" height="{h}" fill="#ffffff"/>',
         text_el(W // 2, 22, title, size=15, weight="bold")]
    heads = [("outstation", "outstation PLC"), ("trm", "TRM-810"), ("mdp", "MDP-810"),
             ("central", "central PLC")]
    o.append(text_el(X_TIME - 8, HEAD_Y + 5, "time", anchor="end", size=11, fill=GREY))
    y_end = top + rows_h + 8
    for key, label in heads:
        x = X[key]
        o.append(f'<line x1="{x}" y1="{HEAD_Y + 12}" x2="{x}" y2="{y_end}" stroke="#bbb" '
                 f'stroke-width="1.2"/>')
        o.append(f'<rect x="{x - 70}" y="{HEAD_Y - 12}" width="140" height="24" rx="5" '
                 f'fill="#eef3f8" stroke="{BLUE}"/>')
        o.append(text_el(x, HEAD_Y + 5, label, weight="bold"))
    # time breaks: the lifelines interrupted by two slashes, the time that passed on the left
    for yb, gap in breaks:
        y = top + yb
        o.append(f'<line x1="{X_TIME}" y1="{y}" x2="{W - 8}" y2="{y}" stroke="#d5d8dc" '
                 f'stroke-width="1" stroke-dasharray="2,4"/>')
        for key, _ in heads:
            x = X[key]
            o.append(f'<rect x="{x - 7}" y="{y - 5}" width="14" height="10" fill="#ffffff"/>')
            o.append(f'<path d="M{x - 7},{y - 1} L{x + 3},{y - 7} M{x - 3},{y + 7} '
                     f'L{x + 7},{y + 1}" stroke="{GREY}" stroke-width="1.2"/>')
        o.append(text_el(X_TIME - 8, y + 4, fmt_gap(gap), anchor="end", size=10, fill=GREY,
                         italic=True, weight="bold"))
    xr = (X["trm"] + X["mdp"]) // 2
    o.append(text_el(xr, HEAD_Y + 26, "~ radio ~", size=11, fill=GREY, italic=True))
    o.append(text_el((X["outstation"] + X["trm"]) // 2, HEAD_Y + 26, "Modbus TCP", size=11,
                     fill=GREY, italic=True))
    o.append(text_el((X["mdp"] + X["central"]) // 2, HEAD_Y + 26, "Modbus TCP", size=11,
                     fill=GREY, italic=True))
    last_t = None
    notes, fg = [], []          # notes first, arrows and their labels on top
    for (t, kind, d), yr in zip(rows, ys):
        y = top + yr
        if t != last_t:
            fg.append(text_el(X_TIME - 8, y + 4, fmt_ms(t), anchor="end", size=10, fill=GREY))
            last_t = t
        reset = kind != "note" and RESET_RE.search(d.get("text", "")) is not None
        text = mark_reset(d["text"]) if reset else d.get("text", "")
        if kind in ("mb_write", "mb_read", "mb_exc", "mb_close"):
            side = d["side"]
            plc, modem = (X["outstation"], X["trm"]) if side == "outstation" else (
                X["central"], X["mdp"])
            if kind == "mb_read":
                fg += arrow(modem, plc, y, GREY, dashed=True, width=1.1)
                color = ORANGE if reset else GREY
            else:
                color = RED if kind != "mb_write" else (ORANGE if reset else BLUE)
                fg += arrow(plc, modem, y, color)
            fg.append(text_el((plc + modem) // 2, y - 4, text, size=11, fill=color, halo=True))
        elif kind == "radio":
            x1, x2 = (X["mdp"], X["trm"]) if d["down"] else (X["trm"], X["mdp"])
            if d["lost"]:
                color = RED
            elif reset:
                color = ORANGE
            elif d["regs"]:
                color = "#222"
            else:
                color = GREY
            fg += arrow(x1, x2, y, color, dashed=d["lost"] or not d["regs"], lost=d["lost"],
                        width=1.8 if d["regs"] else 1.0)
            fg.append(text_el(xr, y - (7 if d["lost"] else 4), text, size=11, fill=color,
                              halo=True))
        elif kind == "note":
            xc = xr if d["side"] == "radio" else X[d["side"]]
            notes += note(xc, y, text, NOTE_FILL.get(d["what"], "#f4f6f7"))
    o += notes + fg
    yb = top + rows_h + 26
    for k, line in enumerate(textwrap.wrap(caption, 150)):
        o.append(text_el(12, yb + 13 * k, line, anchor="start", size=10, fill=GREY))
    o.append("</svg>")
    return "\n".join(o) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="seqdiag", description=__doc__.splitlines()[0])
    ap.add_argument("trace")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--title", default="MIP link")
    ap.add_argument("--caption", default="")
    ap.add_argument("--station", type=int, default=1)
    ap.add_argument("--from-ms", type=int, default=0)
    ap.add_argument("--to-ms", type=int, default=None)
    a = ap.parse_args(argv)
    try:
        events = load(a.trace)
    except TraceError as e:
        print(e, file=sys.stderr)
        return 1
    t_to = a.to_ms * 1_000_000 if a.to_ms is not None else 1 << 62
    try:
        rows = rows_from(events, a.station, a.from_ms * 1_000_000, t_to)
    except (TypeError, ValueError, KeyError, AttributeError) as e:
        print(f"seqdiag: error: {a.trace}: a trace line has a field of the wrong type ({e})",
              file=sys.stderr)
        return 1
    caption = a.caption or ("From the trace " + a.trace.split("/")[-1]
                            + "; empty polls/answers and PLC reads without new data omitted.")
    svg = render(rows, a.title, caption)
    return oneline.write_output("seqdiag", a.output, svg)


if __name__ == "__main__":
    sys.exit(main())
