"""The import graph of our Python packages: the picture of docs/dev/architecture.md and the
module cycles.

    PYTHONPATH=kit .venv/bin/python -m mipdocs.importgraph -o docs/img/import-graph.svg
    PYTHONPATH=kit .venv/bin/python -m mipdocs.importgraph --cycles

The packages and their layers are read from the import contracts (.importlinter, the one
place that names them); the arrows are the imports grimp finds between the packages (one
arrow per pair, whatever the number of import lines). An arrow that points up or sideways
(a broken layer contract) is drawn red. The same imports give the same bytes.
(PYTHONPATH=kit: mipkit is not installed into the venv, pytest.ini puts kit/ on the path.)
"""
from __future__ import annotations

import argparse
import configparser
import importlib.util
import sys
from pathlib import Path
from xml.sax.saxutils import escape

REPO = Path(__file__).resolve().parents[2]
CONTRACTS = REPO / ".importlinter"

FONT = "DejaVu Sans, Verdana, Arial, sans-serif"
BOX_W, BOX_H = 200, 44
GAP_X, ROW_H = 50, 96
MARGIN = 30


class GraphError(Exception):
    """What is wrong with the contracts file (one line for the user)."""


def read_contracts(path=CONTRACTS):
    """(root packages, layers top first: each a list of packages) from an import-linter INI."""
    cp = configparser.ConfigParser()
    try:
        with open(path, encoding="utf-8") as f:
            cp.read_file(f)
    except OSError as e:
        raise GraphError(f"{path}: {e.strerror}") from None
    except configparser.Error as e:
        raise GraphError(f"{path}: not an INI file ({str(e).splitlines()[0]})") from None
    if not cp.has_option("importlinter", "root_packages"):
        raise GraphError(f"{path}: no root_packages in [importlinter]")
    roots = cp.get("importlinter", "root_packages").split()
    for name in cp.sections():
        if name.startswith("importlinter:contract:") and cp.get(name, "type", fallback="") == "layers":
            layers = [[p.strip() for p in line.replace(":", "|").split("|") if p.strip()]
                      for line in cp.get(name, "layers").splitlines() if line.strip()]
            return roots, layers
    raise GraphError(f"{path}: no contract of type = layers")


def build_graph(roots):
    import grimp
    missing = [r for r in roots if importlib.util.find_spec(r) is None]
    if missing:
        raise GraphError(f"package(s) {', '.join(missing)} not importable (make venv; "
                         "PYTHONPATH=kit for mipkit)")
    return grimp.build_graph(*roots, cache_dir=None)


def package_edges(graph):
    """{(importer package, imported package)} of the imports between two of our packages."""
    edges = set()
    for m in graph.modules:
        for imp in graph.find_modules_directly_imported_by(m):
            a, b = m.split(".")[0], imp.split(".")[0]
            if a != b:
                edges.add((a, b))
    return edges


def module_cycles(graph):
    """Every set of modules that import each other in a circle (strongly connected
    components of more than one module, or a module that imports itself), sorted."""
    adj = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in sorted(graph.modules)}
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in adj:
        if root in index:
            continue
        work = [(root, 0)]
        while work:           # Tarjan's algorithm without recursion
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = counter
                counter += 1
                stack.append(v)
                on.add(v)
            if i < len(adj[v]):
                work.append((v, i + 1))
                w = adj[v][i]
                if w not in index:
                    work.append((w, 0))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1 or v in adj[v]:
                    out.append(sorted(comp))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[v])
    return sorted(out)


def folder_of(pkg):
    spec = importlib.util.find_spec(pkg)
    loc = Path(list(spec.submodule_search_locations)[0]).resolve()
    try:
        return loc.relative_to(REPO).as_posix() + "/"
    except ValueError:
        return loc.name + "/"


def render(layers, edges, folders):
    """The SVG: one row per layer (top first), a box per package, an arrow per import edge."""
    width = 2 * MARGIN + max(len(row) for row in layers) * (BOX_W + GAP_X) - GAP_X
    height = 2 * MARGIN + 24 + len(layers) * ROW_H - (ROW_H - BOX_H) + 48
    pos, rank = {}, {}
    for r, row in enumerate(layers):
        row_w = len(row) * (BOX_W + GAP_X) - GAP_X
        x0 = (width - row_w) / 2
        for i, pkg in enumerate(row):
            pos[pkg] = (x0 + i * (BOX_W + GAP_X), MARGIN + 24 + r * ROW_H)
            rank[pkg] = r
    edges = sorted(e for e in edges if e[0] in pos and e[1] in pos)

    def anchors(pkg, ends):
        # spread the arrows over the box's side, in the order of the box at their other end
        ends = sorted(ends, key=lambda o: (pos[o][0], o))
        x, _ = pos[pkg]
        return {o: x + BOX_W * (k + 1) / (len(ends) + 1) for k, o in enumerate(ends)}

    out_x = {p: anchors(p, [b for a, b in edges if a == p]) for p in pos}
    in_x = {p: anchors(p, [a for a, b in edges if b == p]) for p in pos}
    s = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
         f'viewBox="0 0 {width:.0f} {height:.0f}" font-family="{FONT}" font-size="12">',
         '<defs><marker id="arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="7" '
         'markerHeight="7" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" '
         'fill="context-stroke"/></marker></defs>',
         f'<rect width="{width:.0f}" height="{height:.0f}" fill="#ffffff"/>',
         f'<text x="{MARGIN}" y="{MARGIN + 4}" font-size="14" font-weight="bold">Our Python '
         'packages in their layers: an arrow is "imports"</text>']
    for a, b in edges:
        x1, y1 = out_x[a][b], pos[a][1] + BOX_H
        x2, y2 = in_x[b][a], pos[b][1]
        ok = rank[b] > rank[a]
        if not ok:       # sideways or up: from the top of the importer to the bottom of the imported
            y1, y2 = pos[a][1], pos[b][1] + BOX_H
        bend = 36 if ok else -36
        colour = "#5d6d7e" if ok else "#c0392b"
        s.append(f'<path d="M{x1:.1f},{y1:.1f} C{x1:.1f},{y1 + bend:.1f} {x2:.1f},{y2 - bend:.1f} '
                 f'{x2:.1f},{y2:.1f}" fill="none" stroke="{colour}" stroke-width="1.2" '
                 f'marker-end="url(#arrow)"><title>{escape(a)} imports {escape(b)}</title></path>')
    for pkg, (x, y) in sorted(pos.items()):
        s.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{BOX_W}" height="{BOX_H}" rx="6" '
                 f'fill="#eaf2f8" stroke="#1f5f99"/>')
        s.append(f'<text x="{x + BOX_W / 2:.1f}" y="{y + 18:.1f}" text-anchor="middle" '
                 f'font-weight="bold">{escape(pkg)}</text>')
        s.append(f'<text x="{x + BOX_W / 2:.1f}" y="{y + 34:.1f}" text-anchor="middle" '
                 f'font-size="11" fill="#444444">{escape(folders.get(pkg, ""))}</text>')
    for k, line in enumerate(("Rows are the layers of .importlinter: a row imports only from the rows "
                              "below it, boxes in one row",
                              "not from each other. Drawn from the imports grimp finds by "
                              "mipdocs.importgraph (docs/dev/architecture.md).")):
        s.append(f'<text x="{MARGIN}" y="{height - MARGIN - 6 + 15 * k:.0f}" font-size="11" '
                 f'fill="#444444">{escape(line)}</text>')
    s.append("</svg>")
    return "\n".join(s) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="importgraph", description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("-o", "--output", help="write the SVG of the package graph here")
    ap.add_argument("--cycles", action="store_true",
                    help="print the module cycles, one per line (exit 1 if there is one)")
    ap.add_argument("--contracts", default=str(CONTRACTS), help="the import-linter INI file")
    a = ap.parse_args(argv)
    if not a.output and not a.cycles:
        ap.error("give -o FILE.svg or --cycles")
    try:
        roots, layers = read_contracts(a.contracts)
        graph = build_graph(roots)
    except GraphError as e:
        print(f"importgraph: error: {e}", file=sys.stderr)
        return 1
    if a.output:
        svg = render(layers, package_edges(graph), {p: folder_of(p) for p in roots})
        with open(a.output, "w", encoding="utf-8") as f:
            f.write(svg)
    if a.cycles:
        cycles = module_cycles(graph)
        for c in cycles:
            print("cycle: " + " <-> ".join(c))
        print(f"{len(graph.modules)} modules in {len(roots)} packages, {len(cycles)} import cycle(s)")
        return 1 if cycles else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
