"""Throughput-versus-loss plot (SVG) from docs/data/throughput-vs-loss.json.

    .venv/bin/python docs/tools/lossplot.py docs/data/throughput-vs-loss.json -o docs/img/throughput-vs-loss.svg

One line per drive (mean over the seeds), a bar from the lowest to the highest run. The
same data give the same bytes.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import textwrap
from xml.sax.saxutils import escape

from stc import oneline

W = 760
L, R, T = 80, 190, 50
PLOT_H = 335
FONT = "DejaVu Sans, Verdana, Arial, sans-serif"
COLORS = {"spontaneous": "#1f5f99", "polled": "#c0392b"}
MARKS = {"spontaneous": "circle", "polled": "square"}


def nice_step(vmax):
    raw = vmax / 5
    mag = 10 ** math.floor(math.log10(raw))
    for m in (1, 2, 2.5, 5, 10):
        if m * mag >= raw:
            return m * mag
    return 10 * mag


def num(v):
    return f"{v:g}"


def render(data, caption):
    caption = [w for line in caption for w in textwrap.wrap(line, 125)]
    B = 75 + 13 * len(caption)
    H = T + PLOT_H + B
    series = data["series"]
    xs = sorted({pt["loss"] for pts in series.values() for pt in pts})
    ymax = max(max(pt["regs_per_s"]) for pts in series.values() for pt in pts if pt["regs_per_s"])
    step = nice_step(ymax)
    ytop = step * math.ceil(ymax / step)
    xmax = max(xs) if xs and max(xs) > 0 else 1.0
    pw, ph = W - L - R, H - T - B

    def px(x):
        return round(L + pw * x / xmax, 1)

    def py(y):
        return round(T + ph * (1 - y / ytop), 1)

    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
         f'viewBox="0 0 {W} {H}" font-family="{FONT}">',
         f'<rect x="0" y="0" width="{W}" height="{H}" fill="#ffffff"/>',
         f'<text x="{W // 2}" y="26" text-anchor="middle" font-size="15" font-weight="bold">'
         f'Logger transfer throughput against radio loss</text>']
    y = 0.0
    while y <= ytop + 1e-9:
        o.append(f'<line x1="{L}" y1="{py(y)}" x2="{L + pw}" y2="{py(y)}" stroke="#e5e5e5"/>')
        o.append(f'<text x="{L - 8}" y="{py(y) + 4}" text-anchor="end" font-size="11" '
                 f'fill="#444">{num(y)}</text>')
        y += step
    for x in xs:
        o.append(f'<line x1="{px(x)}" y1="{T}" x2="{px(x)}" y2="{T + ph}" stroke="#f0f0f0"/>')
        o.append(f'<text x="{px(x)}" y="{T + ph + 18}" text-anchor="middle" font-size="11" '
                 f'fill="#444">{num(round(x * 100, 1))} %</text>')
    o.append(f'<rect x="{L}" y="{T}" width="{pw}" height="{ph}" fill="none" stroke="#888"/>')
    o.append(f'<text x="{L + pw // 2}" y="{T + ph + 42}" text-anchor="middle" font-size="12">'
             f'telegram loss probability (each direction)</text>')
    o.append(f'<text x="20" y="{T + ph // 2}" text-anchor="middle" font-size="12" '
             f'transform="rotate(-90 20 {T + ph // 2})">payload registers per second</text>')
    for i, (name, pts) in enumerate(sorted(series.items())):
        color = COLORS.get(name, "#555")
        pts = sorted(pts, key=lambda p: p["loss"])
        pts = [p for p in pts if p["regs_per_s"]]
        means = [(p["loss"], sum(p["regs_per_s"]) / len(p["regs_per_s"])) for p in pts]
        path = " ".join(f"{'M' if j == 0 else 'L'}{px(x)},{py(m)}" for j, (x, m) in
                        enumerate(means))
        o.append(f'<path d="{path}" fill="none" stroke="{color}" stroke-width="2"/>')
        for p in pts:
            lo, hi = min(p["regs_per_s"]), max(p["regs_per_s"])
            o.append(f'<line x1="{px(p["loss"])}" y1="{py(lo)}" x2="{px(p["loss"])}" '
                     f'y2="{py(hi)}" stroke="{color}" stroke-width="1.2"/>')
        for x, m in means:
            if MARKS.get(name) == "square":
                o.append(f'<rect x="{px(x) - 4}" y="{py(m) - 4}" width="8" height="8" '
                         f'fill="{color}"/>')
            else:
                o.append(f'<circle cx="{px(x)}" cy="{py(m)}" r="4.5" fill="{color}"/>')
        ly = T + 20 + 22 * i
        o.append(f'<line x1="{L + pw + 16}" y1="{ly}" x2="{L + pw + 40}" y2="{ly}" '
                 f'stroke="{color}" stroke-width="2"/>')
        o.append(f'<text x="{L + pw + 46}" y="{ly + 4}" font-size="12">{escape(name)}</text>')
    ly = T + 20 + 22 * len(series) + 6
    o.append(f'<text x="{L + pw + 16}" y="{ly}" font-size="10" fill="#666">mean of the runs '
             f'of {data.get("seeds", "?")} seeds;</text>')
    o.append(f'<text x="{L + pw + 16}" y="{ly + 13}" font-size="10" fill="#666">bar: lowest '
             f'to highest</text>')
    for k, line in enumerate(caption):
        o.append(f'<text x="12" y="{H - 12 + 13 * (k - len(caption) + 1)}" font-size="10" '
                 f'fill="#666">{escape(line)}</text>')
    o.append("</svg>")
    return "\n".join(o) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="lossplot", description=__doc__.splitlines()[0])
    ap.add_argument("data")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    try:
        with open(a.data, encoding="utf-8") as f:
            data = json.load(f)
        series = data["series"]
        for pts in series.values():
            for p in pts:
                float(p["loss"])
                [float(v) for v in p["regs_per_s"]]
    except OSError as e:
        print(f"lossplot: error: {a.data}: {e.strerror}", file=sys.stderr)
        return 1
    except (ValueError, KeyError, TypeError) as e:
        print(f"lossplot: error: {a.data}: not a throughput data file ({e})", file=sys.stderr)
        return 1
    stuck = [f"{name} {p['loss'] * 100:g} %: seed(s) {', '.join(map(str, p['unfinished_seeds']))}"
             for name, pts in sorted(data["series"].items()) for p in pts
             if p.get("unfinished_seeds")]
    caption = [f"Source: {data.get('source', '?')}.",
               f"{data.get('records', '?')} records of {data.get('payload_per_record', '?')} "
               f"payload registers per transfer; radio: {data.get('radio', '?')};",
               f"PLC: {data.get('plc', '?')}; measured from the {data.get('measured', 'start to the end')}."]
    if stuck:
        caption.append(f"Not finished within {data.get('limit_s', '?')} s and left out: "
                       + "; ".join(stuck) + ".")
    svg = render(data, caption)
    return oneline.write_output("lossplot", a.output, svg)


if __name__ == "__main__":
    sys.exit(main())
