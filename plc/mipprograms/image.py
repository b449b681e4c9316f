"""The located image of the example logger programs, described once.

The logic of each logger program in plc/ is ST written by hand (plc/<name>.st: FUNCTION_BLOCK
<Program>Logic, working on structures, never on a located variable). Only its located image is
generated, from this description, into plc/image/<name>_io.st (first line: "generated ... do
not edit"): PROGRAM <Program> with one located scalar per register (`AT %IX / %IW / %QX / %QW /
%MW`), the copies into the structures (PLC_T_Params, PLC_T_Modem per modem range,
PLC_T_RcvStatus, PLC_T_SndStatus, PLC_T_Window), the call of the logic (instance app, RETAIN)
with them as VAR_IN_OUT, the copies out, and the CONFIGURATION.

Why so (checked with upstream matiec, the matiec fork stock OpenPLC ships and stc; plc/README.md
"Hand-written logic, generated image"): OpenPLC binds only the first register of a located
ARRAY, so the image stays scalar and the copies are generated; a FUNCTION_BLOCK cannot hold
located variables (matiec), so they are in the PROGRAM; unlocated VAR_GLOBALs break upstream
matiec's LOCATED_VARIABLES.h, so the structures are the PROGRAM's and go to the logic by
reference; matiec wants a block declared before its use, so the logic comes first.

The %MW words are defined once: the order of the members of PLC_T_Params, PLC_T_RcvStatus and
PLC_T_SndStatus in plc/PLC_Logger.st (member k at the block's base + k), read from that ST file
with stc's parser (status_members) by the generator and by the co-simulation's P_* / R_* / S_*
numbers (mipcosim.programs). Only the bases are given here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from . import mipglue as glue

PLC_DIR = Path(__file__).resolve().parents[1]
TYPES_FILE = PLC_DIR / "PLC_Logger.st"        # where the image's types are declared
if (Path(__file__).resolve().parent / "PLC_Logger.st").is_file():
    TYPES_FILE = Path(__file__).resolve().parent / "PLC_Logger.st"   # in the test kit's wheel (kit/)
IMAGE_DIR = "image"                            # plc/image/<name>_io.st
READ_REGS, WRITE_REGS, WINDOW = 125, 123, 160
SND_OFFSET, WIN_OFFSET = 20, 40                # in a peer's block: sender status, window
PARAMS_BASE = 0                                # PLC_T_Params at %MW0..
SNAP_REQUEST, SNAP_SAVED = "%QX8.0", "%IW8"     # the runtime's snapshot handshake (docs/retain.md)


class ImageError(Exception):
    """One line: what is wrong with the types the image needs."""


def peer_base(s: int) -> int:
    """%MW of peer s's status block (receiver at +0, sender at +20, window at +40)."""
    return 100 + 200 * (s - 1)


@lru_cache(maxsize=None)
def struct_members(type_name: str, path: str = str(TYPES_FILE)) -> tuple[str, ...]:
    """The member names of STRUCT `type_name` in the ST file `path`, in order (stc's parser)."""
    from stc import syntax as S
    from stc.diag import Diagnostics
    from stc.parser import parse
    diags = Diagnostics()
    text = Path(path).read_text(encoding="utf-8")
    lines = text.split("\n")
    nodes = parse(text, path, diags)
    if nodes is None or diags:
        raise ImageError(diags.format()[0] if diags else f"{path}: error: cannot parse")
    for n in nodes:
        if isinstance(n, S.TypeDecl):
            for d in n.defs:
                if d.name.upper() == type_name.upper() and isinstance(d.spec, S.StructSpec):
                    # the names as written (the parser keeps them upper case): from the text
                    return tuple(lines[ln - 1][col - 1:col - 1 + len(name)]
                                 for v in d.spec.members for name, (ln, col) in v.names)
    raise ImageError(f"{path}: error: no STRUCT {type_name}")


def status_members(kind: str) -> tuple[str, ...]:
    """The %MW words of the parameters ("par", member k at %MW k) or of a receiver's ("rcv")
    or sender's ("snd") status block (member k at its base + k)."""
    return struct_members({"par": "PLC_T_Params", "rcv": "PLC_T_RcvStatus",
                           "snd": "PLC_T_SndStatus"}[kind])


# PLC_T_Modem's members: (member, direction, located address of range s)
MODEM_BITS = (("xRdTrig", "out", "%QX{s}.0"), ("xRdDone", "in", "%IX{s}.0"),
              ("xRdErr", "in", "%IX{s}.1"), ("wRdSt", "in", "%IW{st}"),
              ("xWrTrig", "out", "%QX{s}.1"), ("xWrDone", "in", "%IX{s}.2"),
              ("xWrErr", "in", "%IX{s}.3"), ("wWrLen", "out", "%QW{s}"))


@dataclass(frozen=True)
class Image:
    """The located image of one program: `stations` modem ranges (station s: handshake bits
    %QXs.0/.1, %IXs.0..3, status %IW(10+s), length %QWs, read block %IW(100+125(s-1)), write
    block %QW(100+123(s-1)), global m<s> : PLC_T_Modem) and per station the status blocks
    `status` (a subset of "rcv", "snd", "win": globals rst<s>, sst<s>, win<s>)."""
    name: str                    # the file: plc/<name>.st, plc/image/<name>_io.st
    program: str                 # the hand-written PROGRAM
    instance: str                # its instance in the CONFIGURATION
    stations: int
    status: tuple = ()
    inputs: frozenset = field(default=frozenset({"wTaken"}))   # status members the PLC reads

    @property
    def glue(self) -> glue.Layout:
        return glue.Layout(read_base=100, read_count=READ_REGS, write_base=100,
                           write_count=WRITE_REGS, stations=self.stations,
                           read_array="m{s}.aRead", write_array="m{s}.aWrite", numbered=True)


IMAGES = [
    Image("outstation", "Outstation", "out0", 1, ("snd",)),
    Image("central", "Central", "cen0", 4, ("rcv", "win")),
    Image("outstation_bidi", "OutstationBidi", "out0", 1, ("rcv", "snd", "win")),
    Image("central_bidi", "CentralBidi", "cen0", 4, ("rcv", "snd", "win")),
]
BY_NAME = {i.name: i for i in IMAGES}


def io_file(name: str) -> str:
    """The generated file of program `name`, relative to plc/."""
    return f"{IMAGE_DIR}/{name}_io.st"


def program_files(name: str) -> list[Path]:
    """The files of program `name` in compile order after st_lib and the helpers: the
    hand-written program, then its generated image (which holds the CONFIGURATION), the
    logger programs' (IMAGES) and the chain's (mipprograms.image_chain, which imports this
    module: so known here by their image file)."""
    files = [PLC_DIR / f"{name}.st"]
    if name in BY_NAME or (PLC_DIR / io_file(name)).is_file():
        files.append(PLC_DIR / io_file(name))
    return files


def _status_words(img: Image, s: int):
    """(global, member, %MW address, direction) of station s's status blocks."""
    out = []
    b = peer_base(s)
    for kind, off, glob in (("rcv", 0, f"rst{s}"), ("snd", SND_OFFSET, f"sst{s}")):
        if kind in img.status:
            for k, m in enumerate(status_members(kind)):
                out.append((glob, m, b + off + k, "in" if m in img.inputs else "out"))
    return out


def globals_of(img: Image) -> list[tuple[str, str]]:
    """(name, type) of the structures the generated PROGRAM passes to the hand-written block
    (VAR_IN_OUT), in the order of its interface."""
    out = [("par", "PLC_T_Params")]
    for s in range(1, img.stations + 1):
        out.append((f"m{s}", "PLC_T_Modem"))
        out += [(f"{g}{s}", typ) for kind, g, typ in (("rcv", "rst", "PLC_T_RcvStatus"),
                                                       ("snd", "sst", "PLC_T_SndStatus"),
                                                       ("win", "win", "PLC_T_Window"))
                if kind in img.status]
    return out


def generate(img: Image, source: str = "plc/mipprograms/image.py") -> str:
    """plc/image/<name>_io.st for `img`: PROGRAM <program> with the located words, the copies
    and the call of the hand-written FUNCTION_BLOCK <program>Logic, and the CONFIGURATION."""
    lay = img.glue
    glue.check(lay, "plcrt")
    head = [f"(* generated by plc/gen_programs.py from {source} and the types in plc/PLC_Logger.st;",
            f"   do not edit. The located image of {img.program}Logic (plc/{img.name}.st, written by",
            "   hand): the located words, copied into its structures before the call and out of them",
            "   after it. *)"]
    located, copy_in, copy_out = [], [], []     # the AT declarations in address order per station
    params_image(status_members("par"), located, copy_in)
    for s in range(1, img.stations + 1):
        modem_image(lay, s, located, copy_in, copy_out)
        for g, m, addr, d in _status_words(img, s):
            located.append(f"  {g}_{m} AT %MW{addr} : WORD;")
            (copy_in if d == "in" else copy_out).append(
                f"{g}.{m} := {g}_{m};" if d == "in" else f"{g}_{m} := {g}.{m};")
        if "win" in img.status:
            b = peer_base(s) + WIN_OFFSET
            located += [f"  win{s}_{i} AT %MW{b + i} : WORD;" for i in range(WINDOW)]
            copy_out += [f"win{s}_{i} := win{s}[{i}];" for i in range(WINDOW)]
    return program_text(head, img.program, img.instance, globals_of(img), located, copy_in,
                        copy_out)


def params_image(members: tuple, located: list, copy_in: list):
    """The parameters (global par, member k at %MW k): all read by the program; appended to
    the two lists."""
    for k, m in enumerate(members):
        located.append(f"  par_{m} AT %MW{PARAMS_BASE + k} : WORD;")
        copy_in.append(f"par.{m} := par_{m};")


def modem_image(lay: glue.Layout, s: int, located: list, copy_in: list, copy_out: list):
    """Station s's modem range (global m<s> : PLC_T_Modem): its handshake words (MODEM_BITS)
    and, through mip-glue, its read and write blocks; appended to the three lists."""
    for m, d, addr in MODEM_BITS:
        a = addr.format(s=s, st=10 + s)
        typ = "BOOL" if m[0] == "x" else "WORD"
        located.append(f"  m{s}_{m} AT {a} : {typ};")
        (copy_in if d == "in" else copy_out).append(
            f"m{s}.{m} := m{s}_{m};" if d == "in" else f"m{s}_{m} := m{s}.{m};")
    located += glue.declarations(lay, s)      # mip-glue's: the read block's, the write block's
    copy_in += glue.read_copies(lay, s, indent="")
    copy_out += glue.write_copies(lay, s, indent="")


def program_text(head: list, program: str, instance: str, structs: list, located: list,
                 copy_in: list, copy_out: list, inputs: tuple = ()) -> str:
    """The generated file: PROGRAM `program` with the structures `structs` ((name, type)), the
    snapshot handshake and the located words, the copies in, the call of <program>Logic
    (instance app; `inputs` more (input, value) of the call), the copies out and the
    CONFIGURATION that runs it as `instance`."""
    call = ", ".join(f"{n} := {n}" for n, _t in structs)
    text = head + [f"PROGRAM {program}", "VAR RETAIN",
                   f"  app : {program}Logic;      (* the program's logic, written by hand *)",
                   "END_VAR", "VAR"]
    text += [f"  {n} : {t};" for n, t in structs]
    text += ["END_VAR", "VAR",
             f"  snapReq AT {SNAP_REQUEST} : BOOL;    (* plcrt [retain] request: a snapshot after this scan *)",
             f"  snapSaved AT {SNAP_SAVED} : WORD;     (* plcrt [retain] saved: snapshots completed *)"]
    text += located + ["END_VAR"] + copy_in
    text += [f"app({call},", "    wSnapshots := snapSaved"
             + "".join(f", {n} := {v}" for n, v in inputs) + ");", "snapReq := app.xSnapshotReq;"]
    text += copy_out + ["END_PROGRAM", "",
             "CONFIGURATION Config0", "  RESOURCE Res0 ON PLC",
             "    TASK tMain(INTERVAL := T#10ms, PRIORITY := 0);",
             f"    PROGRAM {instance} WITH tMain : {program};",
             "  END_RESOURCE", "END_CONFIGURATION"]
    return "\n".join(text) + "\n"
