"""Block reference (Markdown) from the doc headers of st_lib/*/*.st: the one source of truth.

    .venv/bin/python docs/tools/blockref.py -o /tmp/blocks.md st_lib/core/*.st  # make docs-blocks: mkdist --reference
    .venv/bin/python docs/tools/blockref.py --check st_lib/*/*.st   # header vs declarations

Every FUNCTION_BLOCK with a `(*@ block NAME ... *)` header gets a section: purpose, the
interface table of the header, behaviour and example. Types come from the TYPE blocks and their
comments. --check (also done on every run) compares each header's interface table with the
VAR_INPUT / VAR_OUTPUT / VAR_IN_OUT declarations and exits 1 when they disagree: a variable
missing on either side, another direction, or a declaration whose trailing comment (what an IDE
shows as its tooltip, and the PLCopen export as its documentation) is missing or says other
than the table's meaning column.
"""
from __future__ import annotations

import argparse
import os
import re
import sys

from mipdocs.stdecl import StError, parse_doc, parse_file
from stc import oneline

LABEL = re.compile(r"^[A-Z][A-Za-z ()/-]{0,40}:(\s|$)")
DIR_OF = {"VAR_INPUT": "in", "VAR_OUTPUT": "out", "VAR_IN_OUT": "in_out"}


def one_line(s):
    return " ".join((s or "").split())


def anchor(name):
    return re.sub(r"[^a-z0-9_-]", "", name.lower().replace(" ", "-"))


def prose(lines):
    """Header text to Markdown: '- ' items become a list, other lines join into paragraphs."""
    out, para, item = [], [], None

    def flush_para():
        if para:
            out.append(" ".join(x.strip() for x in para))
            out.append("")
            para.clear()

    for line in lines:
        if not line.strip():
            flush_para()
            if item is not None:
                out.append(item)
                item = None
            continue
        if line.lstrip().startswith("- "):
            flush_para()
            if item is not None:
                out.append(item)
            item = "- " + line.strip()[2:]
        elif item is not None and line.startswith("  "):
            item += " " + line.strip()
        else:
            if item is not None:
                out.append(item)
                out.append("")
                item = None
            if para and LABEL.match(line):
                flush_para()
            para.append(line)
    if item is not None:
        out.append(item)
        out.append("")
    flush_para()
    return out


def uses_and_defines(units):
    """({file: names it declares}, {file: names declared elsewhere it uses}), upper-case: the
    types of its declarations and the FUNCTIONs called in its bodies."""
    defines, uses = {}, {}
    for u in units:
        names = {t.name.upper() for t in u.types} | {p.name.upper() for p in u.pous}
        defines[u.file] = names
        used = set()
        for p in u.pous:
            for s in p.sections:
                for v in s.vars:
                    t = v.type
                    while t.kind == "array":
                        t = t.base
                    if t.kind == "derived":
                        used.add(t.name.upper())
        for t in u.types:
            if t.spec is not None and t.spec.kind == "derived":
                used.add(t.spec.name.upper())
        for p in u.pous:                      # FUNCTIONs called in a body
            used |= {w.upper() for w in re.findall(r"\b([A-Za-z_]\w*)\s*\(", p.body or "")}
        uses[u.file] = used - names
    return defines, uses


def dependency_order(units):
    """Files in an order in which every type and FB is declared before it is used."""
    defines, uses = uses_and_defines(units)
    order, done = [], set()
    pending = [u.file for u in units]
    while pending:
        progress = False
        for f in list(pending):
            needed = {g for g in pending if g != f and uses[f] & defines[g]}
            if not needed:
                order.append(f)
                pending.remove(f)
                done.add(f)
                progress = True
        if not progress:          # a cycle or an external name: keep the given order
            order += pending
            break
    return order


def check(units):
    """Interface rows of each header against the declarations. Returns a list of messages."""
    problems = []
    for u in units:
        for p in u.pous:
            if not p.doc:
                if p.kind == "FUNCTION_BLOCK":
                    problems.append(f"{u.file}:{p.line}: {p.name}: no (*@ block ... *) header")
                continue
            d = parse_doc(p.doc)
            if d["name"] != p.name:
                problems.append(f"{u.file}:{p.line}: header names {d['name']!r}, "
                                f"the block is {p.name}")
            documented, meaning = {}, {}
            head = d["interface"][0] if d["interface"] else []
            mcol = head.index("meaning") if "meaning" in head else None
            for row in d["interface"][1:]:
                for n in row[0].split(","):
                    documented[n.strip().upper()] = row[1] if len(row) > 1 else ""
                    if mcol is not None and mcol < len(row):
                        meaning[n.strip().upper()] = row[mcol]
            declared = {}
            for s in p.sections:
                if s.kind in DIR_OF:
                    for v in s.vars:
                        declared[v.name.upper()] = (v.name, DIR_OF[s.kind], v)
            for key, (name, direction, v) in declared.items():
                if key not in documented:
                    problems.append(f"{u.file}:{p.line}: {p.name}.{name} ({direction}) is not "
                                    f"in the header's interface table")
                    continue
                if documented[key] and documented[key] != direction:
                    problems.append(f"{u.file}:{p.line}: {p.name}.{name}: header says "
                                    f"{documented[key]}, declared {direction}")
                # the declaration's trailing comment is what an IDE shows (tooltip, PLCopen
                # documentation): it says the same as the header's meaning column
                if not v.comment:
                    problems.append(f"{u.file}:{v.line}: {p.name}.{name} has no trailing "
                                    f"comment (the header's meaning: {meaning.get(key, '')!r})")
                elif key in meaning and one_line(v.comment) != one_line(meaning[key]):
                    problems.append(f"{u.file}:{v.line}: {p.name}.{name}: the trailing comment "
                                    f"differs from the header's meaning column")
            for key in documented:
                if key not in declared:
                    problems.append(f"{u.file}:{p.line}: {p.name}: the header documents "
                                    f"{key}, which is not declared")
    return problems


LIVE = "live"
SAMPLED_BEGIN = "<!-- generated by docs/tools/blockref.py --write-sampled: edit the 'sampled' column of the headers -->"
SAMPLED_END = "<!-- end of generated list -->"
# the condition of a latch: the parameters follow the inputs until the edge (P26)
LATCH = re.compile(r"^\s*(NOT\s+XENABLE\s+OR\s+XENABLERISE\b|XEXECUTERISE\b|XIDLESTATE\b)")


def header_rows(p):
    """[(name, dir, sampled)] of a block's interface table (grouped rows split), or None
    when the table has no 'sampled' column."""
    d = parse_doc(p.doc)
    if not d["interface"] or "sampled" not in d["interface"][0]:
        return None
    col = d["interface"][0].index("sampled")
    out = []
    for row in d["interface"][1:]:
        for n in row[0].split(","):
            out.append((n.strip(), row[1] if len(row) > 1 else "",
                        row[col] if col < len(row) else ""))
    return out


def _code_lines(body):
    return re.sub(r"\(\*.*?\*\)", lambda m: " " * len(m.group()) if "\n" not in m.group()
                  else "\n" * m.group().count("\n"), body, flags=re.S).split("\n")


def latch_use(p, fb_types, headers):
    """What the body does with each input: {input (upper case): 'live' | 'rise of X' |
    'rise of ?'}. An input read only inside a latch (an IF whose condition names an edge
    memory ...Rise or the idle state, with its assignments) is sampled at that edge; one passed
    to an input of an inner block takes the inner block's column for that input; any other
    use is live."""
    instances = {v.name.upper(): v.type.name for s in p.sections for v in s.vars
                 if v.type.kind == "derived" and v.type.name in fb_types}
    lines = _code_lines(p.body)
    text = "\n".join(lines)
    # the argument lists of the inner blocks' calls: name(... P := expr ...);
    args = []
    for m in re.finditer(r"^\s*(\w+)\s*\(", text, re.M):
        inst = m.group(1).upper()
        if inst not in instances:
            continue
        depth, j = 1, m.end()
        while depth and j < len(text):
            depth += {"(": 1, ")": -1}.get(text[j], 0)
            j += 1
        inner = text[m.end():j - 1]
        for a in re.finditer(r"(\w+)\s*:=\s*([^,]*?)\s*(?=,|$)", inner, re.S):
            args.append((m.end() + a.start(2), m.end() + a.end(2), instances[inst],
                         a.group(1), a.group(2)))
    # the IF condition around each line (innermost)
    conds, stack = [], []
    for line in lines:
        u = line.upper()
        opened = re.search(r"\bIF\b(.*?)\bTHEN\b", u)
        closes = len(re.findall(r"\bEND_IF\b", u))
        if opened:
            stack.append(opened.group(1))
        conds.append(stack[-1] if stack else "")
        for _ in range(closes):
            if stack:
                stack.pop()
    starts = [0]
    for line in lines:
        starts.append(starts[-1] + len(line) + 1)
    inputs = [v.name for s in p.sections if s.kind in ("VAR_INPUT", "VAR_IN_OUT") for v in s.vars]
    out = {}
    for name in inputs:
        kinds = set()
        for m in re.finditer(rf"\b{re.escape(name)}\b(?!\s*(?::=|=>))", text, re.I):
            arg = next((a for a in args if a[0] <= m.start() < a[1]), None)
            if arg is not None and arg[4].strip().upper() == name.upper():
                inner = headers.get(arg[2].upper(), {})
                kinds.add(inner.get(arg[3].upper(), LIVE))
                continue
            ln = next(i for i in range(len(lines)) if starts[i] <= m.start() < starts[i + 1])
            cond = conds[ln]
            if LATCH.match(cond):
                # (MIP_Sender's latch is its idle state: until xExecute starts a transfer)
                edge = ("xEnable" if "XENABLE" in cond else "xExecute"
                        if "XEXECUTE" in cond or "XIDLESTATE" in cond else "?")
                kinds.add(f"rise of {edge}")
            else:
                kinds.add(LIVE)
        if not kinds or LIVE in kinds:
            out[name.upper()] = LIVE
        elif len(kinds) == 1:
            out[name.upper()] = kinds.pop()
        else:
            known = {k for k in kinds if not k.endswith("?")}
            out[name.upper()] = known.pop() if len(known) == 1 else "rise of ?"
    return out


def check_sampled(units):
    """The 'sampled' column of each header against what the body does with the input."""
    problems = []
    fbs = {p.name.upper(): p for u in units for p in u.pous if p.kind == "FUNCTION_BLOCK"}
    headers = {}
    for name, p in fbs.items():
        rows = header_rows(p) if p.doc else None
        if rows is not None:
            headers[name] = {n.upper(): s for n, d, s in rows if d in ("in", "in_out")}
    done, pending = set(), [n for n in fbs if n in headers]
    # inner blocks first: a block's column may be the one of the block it passes the input to
    while pending:
        for name in list(pending):
            p = fbs[name]
            inner = {v.type.name.upper() for s in p.sections for v in s.vars
                     if v.type.kind == "derived"} & set(pending)
            if inner - {name}:
                continue
            pending.remove(name)
            use = latch_use(p, {q.name for q in fbs.values()}, headers)
            u = next(u for u in units if p in u.pous)
            for key, said in headers[name].items():
                got = use.get(key)
                if got is None:
                    continue
                if (said == LIVE) != (got == LIVE) or (
                        got != LIVE and not got.endswith("?") and said != got):
                    problems.append(f"{u.file}:{p.line}: {p.name}.{key}: the header says sampled "
                                    f"'{said}', the code: '{got}'")
            done.add(name)
        else:
            continue
    return problems


def sampled_list(units):
    """The generated Markdown list: per block, which inputs are sampled at which edge."""
    order = dependency_order(units)
    by_file = {u.file: u for u in units}
    out = []
    for f in order:
        for p in by_file[f].pous:
            rows = header_rows(p) if p.doc else None
            if not rows:
                continue
            edges = {}
            for n, d, s in rows:
                if d in ("in", "in_out") and s and s != LIVE:
                    edges.setdefault(s, []).append(n)
            if not edges:
                continue
            live = [n for n, d, s in rows if d in ("in", "in_out") and s == LIVE]
            parts = [f"at the {edge.replace('rise of', 'rising edge of')[:-len(edge.split()[-1])]}"
                     f"`{edge.split()[-1]}`: " + ", ".join(f"`{n}`" for n in names)
                     for edge, names in edges.items()]
            out.append(f"- `{p.name}`: " + "; ".join(parts) + "; live: "
                       + ", ".join(f"`{n}`" for n in live))
    return "\n".join(out) + "\n"


def write_sampled(path, text):
    """Replaces the generated region of path. Returns an error message or None."""
    try:
        with open(path, encoding="utf-8") as f:
            old = f.read()
    except OSError as e:
        return f"blockref: error: {path}: {e.strerror}"
    if old.count(SAMPLED_BEGIN) != 1 or old.count(SAMPLED_END) != 1:
        return f"blockref: error: {path}: no region between the generated-list markers"
    a = old.index(SAMPLED_BEGIN) + len(SAMPLED_BEGIN)
    b = old.index(SAMPLED_END)
    new = old[:a] + "\n" + text + old[b:]
    if new != old:
        with open(path, "w", encoding="utf-8") as f:
            f.write(new)
    return None


def render(units, sources_label, order=None, title="Block reference", intro=()):
    """The reference of units (in `order`, default: the dependency order), under `title`, with
    the paragraphs `intro` after the generated-by line."""
    order = order or dependency_order(units)
    by_file = {u.file: u for u in units}
    o = [f"# {title}",
         "",
         f"Generated by `make docs` (`docs/tools/blockref.py`) from the doc headers in "
         f"{sources_label}; do not edit by hand: change the header in the `.st` file.",
         ""]
    for para in intro:
        o += [para, ""]
    o += ["Import the files into the PLC project in this order (each needs only the ones before "
          "it):",
          ""]
    for i, f in enumerate(order, 1):
        o.append(f"{i}. `{os.path.relpath(f, REPO) if os.path.isabs(f) else f}`")
    o.append("")
    blocks = [(u, p) for f in order for u in [by_file[f]] for p in u.pous if p.doc]
    types = [t for f in order for t in by_file[f].types]
    o.append("Contents: [types](#types)" + "".join(f", [{p.name}](#{anchor(p.name)})"
                                                    for _, p in blocks))
    o.append("")
    o.append("## Types")
    o.append("")
    arrays = [t for t in types if t.kind in ("array", "alias")]
    if arrays:
        o += ["| type | definition | meaning |", "|---|---|---|"]
        for t in arrays:
            o.append(f"| `{t.name}` | `{t.spec.text()}` | {one_line(t.comment)} |")
        o.append("")
    for t in types:
        if t.kind == "enum":
            o.append(f"### {t.name}")
            o.append("")
            if t.comment:
                o += [one_line(t.comment), ""]
            o += ["| value | as integer | meaning |", "|---|---|---|"]
            for i, (v, c) in enumerate(t.values):
                o.append(f"| `{v}` | {i} | {one_line(c)} |")
            o.append("")
        elif t.kind == "struct":
            o += [f"### {t.name}", "", one_line(t.comment), "",
                  "| member | type | meaning |", "|---|---|---|"]
            for m in t.members:
                o.append(f"| `{m.name}` | `{m.type.text()}` | {one_line(m.comment)} |")
            o.append("")
    for u, p in blocks:
        d = parse_doc(p.doc)
        sec = d["sections"]
        rel = os.path.relpath(u.file, REPO) if os.path.isabs(u.file) else u.file
        returns = f", returns `{p.return_type.text()}`" if p.return_type is not None else ""
        o += [f"## {p.name}", "", f"`{p.kind}` in `{rel}`{returns}.", ""]
        o += prose(sec.get("purpose", []))
        rows = d["interface"]
        if len(rows) > 1:
            header, body = rows[0], rows[1:]
            o.append("| " + " | ".join(header) + " |")
            o.append("|" + "---|" * len(header))
            for r in body:
                r = r + [""] * (len(header) - len(r))
                names = ", ".join(f"`{n.strip()}`" for n in r[0].split(","))
                typ = f"`{r[2]}`" if len(r) > 2 and r[2] else ""
                dflt = f"`{r[3]}`" if len(r) > 3 and r[3] else ""
                o.append("| " + " | ".join([names, r[1], typ, dflt] + r[4:]) + " |")
            o.append("")
        if sec.get("behaviour"):
            o += ["### Behaviour", ""] + prose(sec["behaviour"])
        if sec.get("example"):
            o += ["### Example", "", "```", *sec["example"], "```", ""]
    while o and o[-1] == "":
        o.pop()
    return "\n".join(o) + "\n"


REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv=None):
    ap = argparse.ArgumentParser(prog="blockref", description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("-o", "--output")
    ap.add_argument("--check", action="store_true", help="only compare headers and declarations")
    ap.add_argument("--sampled", action="store_true",
                    help="print the list of sampled inputs (from the headers' 'sampled' column)")
    ap.add_argument("--write-sampled", metavar="FILE", action="append", default=[],
                    help="replace the generated list of sampled inputs in FILE")
    a = ap.parse_args(argv)
    try:
        units = [parse_file(f) for f in a.files]
    except StError as e:
        print(e, file=sys.stderr)
        return 1
    problems = check(units) + check_sampled(units)
    for p in problems:
        print(f"{p}", file=sys.stderr)
    if a.check:
        return 1 if problems else 0
    if a.sampled or a.write_sampled:
        text = sampled_list(units)
        if a.sampled:
            sys.stdout.write(text)
        for path in a.write_sampled:
            err = write_sampled(path, text)
            if err:
                print(err, file=sys.stderr)
                return 1
        return 1 if problems else 0
    if not a.output:
        print("blockref: error: -o FILE is required (or --check)", file=sys.stderr)
        return 2
    dirs = {os.path.dirname(f) or "." for f in a.files}
    label = " ".join(f"`{d}/*.st`" for d in sorted(dirs))
    text = render(units, label)
    return oneline.write_output("blockref", a.output, text, status=1 if problems else 0)


if __name__ == "__main__":
    sys.exit(main())
