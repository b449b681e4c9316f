"""mip-glue: writes the located-variable glue between a Modbus master's image and the MIP blocks.

    mip-glue [layout options] [--form fragment|program]      (prints the glue)
    mip-glue [layout options] --update FILE | --check FILE    (its marked regions in FILE)

Portable ST (matiec, OpenPLC) cannot index located variables and has no located arrays, so the
modem's read block in %IWn.. and the write block in %QWn.. need one WORD variable and one
statement per register (`aRd[i] := r<i>;`, `w<i> := aWr[i];`): 248 lines for one station. This
command writes them: the `AT %IW` / `AT %QW` declarations (one VAR block) and the copies, per
station (a central serving several stations: read block of station s at read base +
(s - 1) x read count, likewise the write blocks; `{s}` in an array name is the station number).

Each part is enclosed in marker comments, `(* BEGIN mip-glue read *)` .. `(* END mip-glue read *)`
(the declarations' marker records the options): paste the fragment into your PROGRAM once;
`--update FILE` then rewrites the regions in place (with no layout option it takes the ones
recorded in FILE), `--check FILE` fails in one line when they differ (for CI). `--form program`
writes a whole PROGRAM skeleton with the arrays declared (a FUNCTION_BLOCK cannot hold
located variables in matiec).

Limits (one-line errors, exit status 2): a runtime's image holds %IW0..%IW1023 and
%QW0..%QW1023 (OpenPLC v3 and plcrt); with --runtime openplc (the default) the blocks must lie
where stock OpenPLC's Modbus master puts them, %IW100..%IW499 and %QW100..%QW499 (MAX_MB_IO,
400 registers per direction over all devices, mipprograms.openplc_limits); a read is at most 125
registers (one FC3, MIP_T_ReadBlock), a write at most 123 (one FC16, MIP_T_Block). With
--update/--check, a located variable of FILE outside the regions on an address of a block is
refused too (one address, two variables).

The same code writes the copies of the repository's example programs (mipprograms.gen,
plc/gen_programs.py).
"""
from __future__ import annotations

import argparse
import re
import shlex
import sys
from dataclasses import dataclass

from .openplc_limits import MAX_MB_IO

PROG = "mip-glue"
IMAGE_SIZE = 1024           # %IW n, %QW n: n < 1024 in OpenPLC v3 and plcrt (PLCRT_IMAGE_SIZE)
OPENPLC_FIRST = 100         # OpenPLC's Modbus master: %IW100.. / %QW100.. (MAX_MB_IO of them)
MAX_READ = 125              # one FC3; MIP_T_ReadBlock is ARRAY[0..124]
MAX_WRITE = 123             # one FC16; MIP_T_Block is ARRAY[0..122]
MAX_STATIONS = 247          # Modbus unit ids behind one MDP-810
RUNTIMES = ("openplc", "plcrt")
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")


class GlueError(Exception):
    """One line: what is wrong with the layout or the file."""


@dataclass(frozen=True)
class Layout:
    """Where the blocks lie in the image and what the copies are called.

    Station s (1..stations) reads %IW(read_base + (s-1)*read_count) .. and writes
    %QW(write_base + (s-1)*write_count) ..; its variables are <prefix><i> (one station, unless
    numbered) or <prefix><s>_<i>; `{s}` in an array name stands for the station number."""
    read_base: int = 100
    read_count: int = MAX_READ
    write_base: int = 100
    write_count: int = MAX_WRITE
    stations: int = 1
    read_array: str = "aRd"
    write_array: str = "aWr"
    read_prefix: str = "r"
    write_prefix: str = "w"
    numbered: bool | None = None        # None: station numbers in the names when stations > 1

    def read_image(self, s: int) -> int:
        return self.read_base + self.read_count * (s - 1)

    def write_image(self, s: int) -> int:
        return self.write_base + self.write_count * (s - 1)

    def var(self, kind: str, s: int, i: int) -> str:
        prefix = self.read_prefix if kind == "read" else self.write_prefix
        numbered = self.stations > 1 if self.numbered is None else self.numbered
        return f"{prefix}{s}_{i}" if numbered else f"{prefix}{i}"

    def array(self, kind: str, s: int) -> str:
        return (self.read_array if kind == "read" else self.write_array).replace("{s}", str(s))


def declarations(lay: Layout, s: int, indent: str = "  ") -> list[str]:
    """The located WORDs of station s: the read block's, then the write block's."""
    out = [f"{indent}{lay.var('read', s, i)} AT %IW{lay.read_image(s) + i} : WORD;"
           for i in range(lay.read_count)]
    out += [f"{indent}{lay.var('write', s, i)} AT %QW{lay.write_image(s) + i} : WORD;"
            for i in range(lay.write_count)]
    return out


def read_copies(lay: Layout, s: int, indent: str = "  ", array: str | None = None) -> list[str]:
    """`array[i] := r<i>;` for the read block of station s."""
    a = array or lay.array("read", s)
    return [f"{indent}{a}[{i}] := {lay.var('read', s, i)};" for i in range(lay.read_count)]


def write_copies(lay: Layout, s: int, indent: str = "  ", array: str | None = None) -> list[str]:
    """`w<i> := array[i];` for the write block of station s."""
    a = array or lay.array("write", s)
    return [f"{indent}{lay.var('write', s, i)} := {a}[{i}];" for i in range(lay.write_count)]


def _span(area: str, first: int, count: int) -> str:
    return f"%{area}W{first}..%{area}W{first + count - 1}"


def check(lay: Layout, runtime: str = "openplc") -> None:
    """GlueError (one line) for a layout that no runtime, or not `runtime`, can hold."""
    if runtime not in RUNTIMES:
        raise GlueError(f"--runtime {runtime}: one of {', '.join(RUNTIMES)}")
    if not 1 <= lay.stations <= MAX_STATIONS:
        raise GlueError(f"--stations {lay.stations}: 1..{MAX_STATIONS} (Modbus unit ids of one MDP-810)")
    if not 1 <= lay.read_count <= MAX_READ:
        raise GlueError(f"--read-count {lay.read_count}: 1..{MAX_READ} registers "
                        f"(one Modbus read, MIP_T_ReadBlock)")
    if not 0 <= lay.write_count <= MAX_WRITE:
        raise GlueError(f"--write-count {lay.write_count}: 0..{MAX_WRITE} registers "
                        f"(one Modbus write, MIP_T_Block; 0: no write block)")
    for opt, v in (("--read-base", lay.read_base), ("--write-base", lay.write_base)):
        if v < 0:
            raise GlueError(f"{opt} {v}: an address is 0 or more")
    for opt, p in (("--read-prefix", lay.read_prefix), ("--write-prefix", lay.write_prefix)):
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", p) or "__" in p + "0":
            raise GlueError(f"{opt} {p!r}: a name starts with a letter, has letters, digits and "
                            f"single underscores (matiec refuses '__' and a trailing '_')")
    for kind in ("read", "write"):
        if kind == "write" and lay.write_count == 0:
            continue
        tmpl = lay.read_array if kind == "read" else lay.write_array
        if lay.stations > 1 and "{s}" not in tmpl:
            raise GlueError(f"--{kind}-array {tmpl}: with --stations {lay.stations} every station "
                            f"needs its own array: put {{s}} (the station number) in the name, "
                            f"e.g. {tmpl}{{s}}")
        name = lay.array(kind, 1)
        if not NAME.fullmatch(name) or "__" in name or name.endswith("_"):
            raise GlueError(f"--{kind}-array {tmpl}: not an ST name (a variable or "
                            f"instance.member; {{s}} for the station number)")
    _check_names(lay)
    last = lay.stations
    blocks = [("read", "I", lay.read_base, lay.read_count * last, "--read-base")]
    if lay.write_count:
        blocks.append(("write", "Q", lay.write_base, lay.write_count * last, "--write-base"))
    for kind, area, first, n, obase in blocks:
        span = _span(area, first, n)
        per = f" ({last} stations x {n // last})" if last > 1 else ""
        if first + n > IMAGE_SIZE:
            raise GlueError(f"the {kind} block{'s' if last > 1 else ''} would take {span}{per}: the image ends at "
                            f"%{area}W{IMAGE_SIZE - 1} (OpenPLC v3 and plcrt)")
        if runtime == "openplc" and (first < OPENPLC_FIRST or first + n > OPENPLC_FIRST + MAX_MB_IO):
            if n > MAX_MB_IO:
                fit = MAX_MB_IO // (n // last)
                what = (f"at most {fit} station{'s' if fit != 1 else ''} of {n // last} "
                        f"registers fit")
            else:
                what = (f"{obase} {OPENPLC_FIRST}..{OPENPLC_FIRST + MAX_MB_IO - n} "
                        f"for {n} registers")
            raise GlueError(f"the {kind} block{'s' if last > 1 else ''} would take {span}{per}: "
                            f"stock OpenPLC v3's Modbus master fills only "
                            f"{_span(area, OPENPLC_FIRST, MAX_MB_IO)} ({MAX_MB_IO} registers, "
                            f"MAX_MB_IO): {what} (or --runtime plcrt: the whole image)")


def _check_names(lay: Layout) -> None:
    """Every generated variable and array has a name of its own (`--read-prefix w1` and
    `--write-prefix w` would both give w10)."""
    seen = {}
    for s in range(1, lay.stations + 1):
        for kind, count in (("read", lay.read_count), ("write", lay.write_count)):
            for i in range(count):
                name = lay.var(kind, s, i).upper()            # ST names ignore case
                if name in seen:
                    raise GlueError(f"--read-prefix {lay.read_prefix!r} and --write-prefix "
                                    f"{lay.write_prefix!r} give two variables the name "
                                    f"{lay.var(kind, s, i)}: pick prefixes that differ")
                seen[name] = kind
    for s in range(1, lay.stations + 1):
        for kind in ("read", "write") if lay.write_count else ("read",):
            base = lay.array(kind, s).split(".")[0]
            if base.upper() in seen:
                raise GlueError(f"--{kind}-array {lay.read_array if kind == 'read' else lay.write_array}:"
                                f" {base} is also the name of a generated located variable")


# ---- marked regions -------------------------------------------------------------------------

BEGIN = re.compile(r"^([ \t]*)\(\* BEGIN mip-glue (declarations|read|write)(?: (\d+))?(?:: (.*?))? \*\)[ \t\r]*$")
END = re.compile(r"^[ \t]*\(\* END mip-glue (declarations|read|write)(?: (\d+))? \*\)[ \t\r]*$")
ANY_MARK = re.compile(r"\(\* *(BEGIN|END) mip-glue\b")


def _part_key(lay: Layout, kind: str, s: int) -> str:
    return kind if kind == "declarations" or lay.stations == 1 else f"{kind} {s}"


def parts(lay: Layout, command: str) -> dict[str, tuple[str, list[str]]]:
    """{region key: (BEGIN marker text after the key, body lines at indent 0)} in file order."""
    decl = ["VAR"]
    for s in range(1, lay.stations + 1):
        decl += declarations(lay, s)
    decl.append("END_VAR")
    out = {"declarations": (f": {command}", decl)}
    for kind, fn in (("read", read_copies), ("write", write_copies)):
        if kind == "write" and lay.write_count == 0:
            continue
        for s in range(1, lay.stations + 1):
            out[_part_key(lay, kind, s)] = ("", fn(lay, s, indent=""))
    return out


def _region(key: str, head: str, body: list[str], indent: str) -> list[str]:
    return ([f"{indent}(* BEGIN mip-glue {key}{head} *)"]
            + [f"{indent}{line}" for line in body]
            + [f"{indent}(* END mip-glue {key} *)"])


def fragment(lay: Layout, command: str) -> str:
    """The declarations' VAR block and the copies, each in its marked region."""
    out = [f"(* {command}: the located image of the MIP blocks' arrays.",
           "   Paste the declarations among your PROGRAM's VAR blocks, the read copies where a",
           "   read completed, the write copies before the write is triggered; then",
           "   `--update FILE` regenerates the regions in place. *)"]
    for key, (head, body) in parts(lay, command).items():
        out += _region(key, head, body, "")
    return "\n".join(out) + "\n"


def program(lay: Layout, command: str, name: str) -> str:
    """A PROGRAM skeleton: the located image, the arrays, the copies, a place for your code."""
    for kind in ("read", "write"):
        if kind == "write" and lay.write_count == 0:
            continue
        if "." in lay.array(kind, 1):
            raise GlueError(f"--form program declares the arrays: --{kind}-array "
                            f"{lay.read_array if kind == 'read' else lay.write_array} is not a "
                            f"plain name (use the fragment, or copy into a plain array)")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name) or "__" in name or name.endswith("_"):
        raise GlueError(f"--program-name {name!r}: not an ST name")
    ps = parts(lay, command)
    out = [f"(* A PROGRAM skeleton written by {command} --form program:",
           "   the modem's blocks in the located image and in the arrays the MIP blocks take.",
           "   Put your code (the MIP block calls) between the read and the write copies; the",
           "   regions between BEGIN and END are regenerated by --update FILE. *)",
           f"PROGRAM {name}"]
    out += _region("declarations", *ps["declarations"], "")
    out.append("VAR")
    for s in range(1, lay.stations + 1):
        out.append(f"  {lay.array('read', s)} : MIP_T_ReadBlock;")
        if lay.write_count:
            out.append(f"  {lay.array('write', s)} : MIP_T_Block;")
    out.append("END_VAR")
    out.append("(* the read blocks, as the master last read them (copy them only when a read "
               "completed if your master has a handshake) *)")
    for s in range(1, lay.stations + 1):
        out += _region(_part_key(lay, "read", s), *ps[_part_key(lay, "read", s)], "")
    out.append("(* your code: the MIP blocks with aRead := the read array, and the write array "
               "filled from their aWrite *)")
    if lay.write_count:
        out.append("(* the write blocks, written by the master (with a handshake: when you "
                   "raise its trigger) *)")
        for s in range(1, lay.stations + 1):
            out += _region(_part_key(lay, "write", s), *ps[_part_key(lay, "write", s)], "")
    out.append("END_PROGRAM")
    return "\n".join(out) + "\n"


def _newline(text: str) -> str:
    """The file's line end (a file saved on Windows keeps its CR LF)."""
    return "\r\n" if "\r\n" in text else "\n"


def _without_comments(text: str) -> str:
    """text with every (* comment *) blanked, line numbers kept."""
    return re.sub(r"\(\*.*?\*\)", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)


def find_regions(text: str, path: str):
    """[(key, first line index, last line index, indent, recorded command)] of FILE's regions."""
    lines = text.split(_newline(text))
    regions, open_ = [], None
    for n, line in enumerate(lines):
        b, e = BEGIN.match(line), END.match(line)
        if b:
            if open_:
                raise GlueError(f"{path}:{n + 1}: BEGIN mip-glue inside the region begun on line "
                                f"{open_[1] + 1} (no END mip-glue {open_[0]} before it)")
            key = b.group(2) + (f" {b.group(3)}" if b.group(3) else "")
            open_ = (key, n, b.group(1), b.group(4))
        elif e:
            key = e.group(1) + (f" {e.group(2)}" if e.group(2) else "")
            if not open_ or open_[0] != key:
                raise GlueError(f"{path}:{n + 1}: END mip-glue {key} without its BEGIN")
            regions.append((key, open_[1], n, open_[2], open_[3]))
            open_ = None
        elif ANY_MARK.search(line):
            raise GlueError(f"{path}:{n + 1}: a mip-glue marker this command does not know: "
                            f"{line.strip()}")
    if open_:
        raise GlueError(f"{path}:{open_[1] + 1}: BEGIN mip-glue {open_[0]} without its END")
    keys = [r[0] for r in regions]
    for k in keys:
        if keys.count(k) > 1:
            raise GlueError(f"{path}: the region mip-glue {k} is there {keys.count(k)} times")
    return regions


def recorded_args(text: str, path: str) -> list[str]:
    """The options recorded in FILE's declarations marker (`: mip-glue OPTIONS`)."""
    for key, _, _, _, cmd in find_regions(text, path):
        if key == "declarations" and cmd:
            try:
                words = shlex.split(cmd)
            except ValueError as e:
                raise GlueError(f"{path}: the declarations marker's command: {e}") from None
            return words[1:] if words and words[0] == PROG else words
    return []


def regenerate(text: str, lay: Layout, command: str, path: str) -> tuple[str, list[tuple[int, str]]]:
    """(FILE's text with every region regenerated, [(first line that differs, key) of the
    regions that changed])."""
    regions = find_regions(text, path)
    want = parts(lay, command)
    have = {r[0] for r in regions}
    for key, first, *_ in regions:
        if key not in want:
            raise GlueError(f"{path}:{first + 1}: the region mip-glue {key} is not part of this "
                            f"layout ({', '.join(want)})")
    for key in want:
        if key not in have:
            raise GlueError(f"{path}: no region (* BEGIN mip-glue {key} *) .. (* END mip-glue {key} *):"
                            f" paste the fragment ({PROG} without --update) into it first")
    nl = _newline(text)
    lines = text.split(nl)
    taken = {}
    for key, first, last, indent, _ in regions:
        for n in range(first, last + 1):
            taken[n] = key
    _check_collisions(_without_comments(text).split(nl), taken, lay, path)
    out, changed, pos = [], [], 0
    for key, first, last, indent, _ in sorted(regions, key=lambda r: r[1]):
        out += lines[pos:first]
        new, old = _region(key, *want[key], indent), lines[first:last + 1]
        if new != old:          # the first line that differs (1-based)
            k = next((k for k, (a, b) in enumerate(zip(new, old)) if a != b), min(len(new), len(old)))
            changed.append((first + k + 1, key))
        out += new
        pos = last + 1
    out += lines[pos:]
    return nl.join(out), changed


def _check_collisions(lines, taken, lay: Layout, path: str):
    """A located WORD of FILE outside the regions on an address of a block: one line."""
    spans = []
    for s in range(1, lay.stations + 1):
        spans.append(("I", lay.read_image(s), lay.read_count, "read", s))
        if lay.write_count:
            spans.append(("Q", lay.write_image(s), lay.write_count, "write", s))
    for n, line in enumerate(lines):
        if n in taken:
            continue
        for m in re.finditer(r"(\w+)\s+AT\s+%([IQ])W(\d+)\b", line):
            name, area, addr = m.group(1), m.group(2), int(m.group(3))
            for a, first, count, kind, s in spans:
                if a == area and first <= addr < first + count:
                    st = f" of station {s}" if lay.stations > 1 else ""
                    raise GlueError(f"{path}:{n + 1}: {name} AT %{area}W{addr} is in the {kind} "
                                    f"block{st} ({_span(area, first, count)}): one address, "
                                    f"two variables")


# ---- the command ----------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    def error(self, message):               # one line, no usage block
        raise GlueError(f"{message} (see {PROG} --help)")


def _address(area):
    def parse(v: str) -> int:
        m = re.fullmatch(rf"(?:%{area}W)?(\d+)", v.strip(), re.I)
        if not m:
            raise argparse.ArgumentTypeError(f"{v!r}: a register number or %{area}Wn")
        return int(m.group(1))
    parse.__name__ = f"%{area}W address"
    return parse


LAYOUT_OPTS = [  # (option, Layout field, type, help)
    ("--read-base", "read_base", _address("I"), "first %%IW of the read block (default 100)"),
    ("--read-count", "read_count", int, f"registers read per station (default {MAX_READ}: the "
                                         f"read-status register and the MIP read area)"),
    ("--write-base", "write_base", _address("Q"), "first %%QW of the write block (default 100)"),
    ("--write-count", "write_count", int, f"registers written per station (default {MAX_WRITE}; "
                                          f"0: no write block)"),
    ("--stations", "stations", int, "stations of a central, blocks one after the other "
                                    "(default 1)"),
    ("--read-array", "read_array", str, "the array the read copies go to, {s}: the station "
                                        "(default aRd)"),
    ("--write-array", "write_array", str, "the array the write copies come from, e.g. "
                                          "snd.aWrite; {s}: the station (default aWr)"),
    ("--read-prefix", "read_prefix", str, "name prefix of the located read variables "
                                          "(default r: r0, r1, ..; stations: r1_0, ..)"),
    ("--write-prefix", "write_prefix", str, "the same for the write variables (default w)"),
]


def _parser() -> _Parser:
    doc = __doc__.split("\n\n")          # title, usage, the rest
    usage = "\n       ".join(line.strip() for line in doc[1].strip().splitlines())
    ap = _Parser(prog=PROG, usage=usage.replace("%", "%%"),
                 description="\n\n".join([doc[0]] + doc[2:]).strip(),
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    for opt, dest, typ, help_ in LAYOUT_OPTS:
        ap.add_argument(opt, dest=dest, type=typ, default=None, help=help_)
    ap.add_argument("--runtime", choices=RUNTIMES, default=None,
                    help="whose limits to check (default openplc: stock OpenPLC v3's Modbus "
                         "master, %%IW100..%%IW499; plcrt: the whole image)")
    ap.add_argument("--form", choices=("fragment", "program"), default="fragment",
                    help="fragment (default): VAR block and copies in marked regions; program: "
                         "a PROGRAM skeleton with the arrays declared")
    ap.add_argument("--program-name", default="Glue", help="the PROGRAM's name (--form program)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--update", metavar="FILE", help="regenerate FILE's marked regions in place")
    g.add_argument("--check", metavar="FILE",
                   help="exit 1 when FILE's marked regions differ from what this command writes")
    return ap


def _command(lay: Layout, runtime: str) -> str:
    """The canonical command for this layout: the options that differ from the defaults."""
    words = [PROG]
    default = Layout()
    for opt, dest, _, _ in LAYOUT_OPTS:
        v = getattr(lay, dest)
        if v != getattr(default, dest):
            words += [opt, str(v)]
    if runtime != "openplc":
        words += ["--runtime", runtime]
    return shlex.join(words)


def run(argv) -> tuple[int, str]:
    """(exit status, output) of the command; GlueError for a one-line error."""
    ap = _parser()
    a = ap.parse_args(argv)
    path = a.update or a.check
    text = None
    if path:
        try:
            with open(path, encoding="utf-8", newline="") as f:     # its line ends as they are
                text = f.read()
        except OSError as e:
            raise GlueError(f"{path}: {e.strerror}") from None
        except UnicodeDecodeError:
            raise GlueError(f"{path}: not UTF-8 text") from None
        given = {dest for opt, dest, _, _ in LAYOUT_OPTS if getattr(a, dest) is not None}
        if not given and a.runtime is None:          # the options recorded in FILE
            recorded = recorded_args(text, path)
            try:
                a = ap.parse_args(recorded + list(argv))
                lay = Layout(**{d: getattr(a, d) for _, d, _, _ in LAYOUT_OPTS if getattr(a, d) is not None})
                check(lay, a.runtime or "openplc")
            except GlueError as e:
                raise GlueError(f"{path}: the options in its declarations marker "
                                f"({shlex.join(recorded)}): {e}") from None
    values = {dest: getattr(a, dest) for _, dest, _, _ in LAYOUT_OPTS if getattr(a, dest) is not None}
    lay = Layout(**values)
    runtime = a.runtime or "openplc"
    check(lay, runtime)
    command = _command(lay, runtime)
    if not path:
        return 0, (program(lay, command, a.program_name) if a.form == "program"
                   else fragment(lay, command))
    new, changed = regenerate(text, lay, command, path)
    if a.check:
        if changed:
            line, key = changed[0]
            return 1, (f"{path}:{line}: the region mip-glue {key} differs from what `{command}` "
                       f"writes (run it with --update {path})")
        return 0, f"{path}: up to date"
    if changed:
        try:
            with open(path, "w", encoding="utf-8", newline="") as f:
                f.write(new)
        except OSError as e:
            raise GlueError(f"{path}: {e.strerror}") from None
        return 0, f"{path}: updated {', '.join(k for _, k in changed)}"
    return 0, f"{path}: up to date"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        status, out = run(argv)
    except GlueError as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        return 2
    except SystemExit as e:                  # --help
        return int(e.code or 0)
    except KeyboardInterrupt:
        return 130
    (sys.stdout if status == 0 else sys.stderr).write(out if out.endswith("\n") else out + "\n")
    return status


if __name__ == "__main__":
    sys.exit(main())
