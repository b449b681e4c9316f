"""The located image of the chain's programs (issue 35, docs/chain.md), described once.

As for the logger programs (mipprograms.image, whose docstring says why the split is so), the
logic of plc/outstation_soe.st, plc/central_soe.st and plc/central_push.st is ST written by hand
(FUNCTION_BLOCK <Program>Logic working on structures) and only their located image is generated
from this description into plc/image/<name>_io.st: the parameters PLC_T_SoeParams (%MW0..),
the modem's ranges (PLC_T_Modem, station 1, as the logger programs'), the chain's own ranges
(RANGES below: the relay's, the SCADA's slave registers, the UNICOS drivers' write ranges) and
the status words (%MW100..). The runtime configs' sections for those ranges
(mipcosim.chainprograms: relay_sections, slave_section, unicos_sections) take their addresses
from the same Range objects, so a range moved here moves in the program and in its config.

The %MW words are defined once: the member order of PLC_T_SoeParams and of the status types in
plc/PLC_SoeChain.st (member k at %MW k, at %MW 100 + k), read with stc's parser
(mipprograms.image.struct_members) here and by the co-simulation's OUT_* / CEN_* / PUSH_*
numbers (mipcosim.chainprograms).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from . import image as I

TYPES_FILE = I.PLC_DIR / "PLC_SoeChain.st"      # the chain programs' types
if (Path(__file__).resolve().parent / "PLC_SoeChain.st").is_file():
    TYPES_FILE = Path(__file__).resolve().parent / "PLC_SoeChain.st"   # in the test kit's wheel
STATUS_BASE = 100          # the status words %MW100..
SOE_BASE = 600             # PDU address of 40601, at the relay and at the central's slave
SOE_REGS = 26              # 40601..40626: count, SOE_Control, 3 message blocks of 8
UNICOS_MARKER = 0xFF80     # the frames' reference number: 16#FFFF + 123 registers would run past
                           # 65535, which plcrt's write range refuses; WinCC OA: [mod] addUnicosMarker
UNICOS_IMAGE = {"a": 400, "b": 530}   # the frames for driver A / B at %QW400.. / %QW530..


def members(type_name: str) -> tuple[str, ...]:
    """The members of STRUCT `type_name` of plc/PLC_SoeChain.st, in order."""
    return I.struct_members(type_name, str(TYPES_FILE))


@dataclass(frozen=True)
class Range:
    """One located range of a program, the structure `glob` : `typ` in the generated PROGRAM:
    `words` ((member, "in" | "out", address)) and `arrays` ((member, direction, first
    register's address, registers): member[i] at address + i). A word at an address an array
    already has (the SCADA's SOE_Control) is read from the array's located word."""
    glob: str
    typ: str
    words: tuple = ()
    arrays: tuple = ()

    def addr(self, member: str) -> str:
        """The located address of `member` (of an array: its first register)."""
        for m, _d, a in self.words:
            if m == member:
                return a
        for m, _d, a, _n in self.arrays:
            if m == member:
                return a
        raise KeyError(member)


def _plus(addr: str, i: int) -> str:
    kind = addr[:3]                           # %IW / %QW
    return f"{kind}{int(addr[3:]) + i}"


# the outstation's ranges at the relay (plcrt [read] soe, [write] soe_control; trigger policy)
RELAY = Range("relay", "PLC_T_SoeRelay", words=(
    ("xRdTrig", "out", "%QX2.0"), ("xRdDone", "in", "%IX2.0"), ("xRdErr", "in", "%IX2.1"),
    ("wRdSt", "in", "%IW12"), ("xWrTrig", "out", "%QX2.1"), ("xWrDone", "in", "%IX2.2"),
    ("xWrErr", "in", "%IX2.3"), ("wWrLen", "out", "%QW2"), ("wWrVal", "out", "%QW300")),
    arrays=(("aRead", "in", "%IW300", SOE_REGS),))
# the pull central's Modbus slave for the SCADA (plcrt [slave]): holding 600..625 = %QW600..,
# the SCADA's writes to SOE_Control (%QW601) counted in %IW9
SCADA = Range("scada", "PLC_T_SoeScada", arrays=(("aRegs", "out", f"%QW{SOE_BASE}", SOE_REGS),),
              words=(("wCtrlWritten", "in", f"%QW{SOE_BASE + 1}"), ("wCtrlWrites", "in", "%IW9")))


def driver(d: str) -> Range:
    """The push central's write range to WinCC OA's UNICOS driver d ("a", "b"; plcrt [write]
    unicos_<d>, trigger policy): handshake bits %QX3.k / %IX3.2k, .2k+1, status %IW(13+k),
    length %QW(3+k), the frame from UNICOS_IMAGE[d]."""
    k = "ab".index(d)
    return Range(f"drv{d.upper()}", "PLC_T_UnicosDriver", words=(
        ("xWrTrig", "out", f"%QX3.{k}"), ("xWrDone", "in", f"%IX3.{2 * k}"),
        ("xWrErr", "in", f"%IX3.{2 * k + 1}"), ("wWrSt", "in", f"%IW{13 + k}"),
        ("wWrLen", "out", f"%QW{3 + k}")),
        arrays=(("aWrite", "out", f"%QW{UNICOS_IMAGE[d]}", I.WRITE_REGS),))


@dataclass(frozen=True)
class ChainImage:
    """The located image of one chain program: the parameters, station 1's modem ranges, the
    chain ranges `ranges` and the status words of STRUCT `status`; `inputs` more inputs of the
    call of the logic ((name, ST value))."""
    name: str
    program: str
    instance: str
    status: str
    ranges: tuple
    inputs: tuple = ()


IMAGES = [
    ChainImage("outstation_soe", "OutstationSoe", "out0", "PLC_T_SoeOutStatus", (RELAY,)),
    ChainImage("central_soe", "CentralSoe", "cen0", "PLC_T_SoeCenStatus", (SCADA,)),
    ChainImage("central_push", "CentralPush", "cen0", "PLC_T_SoePushStatus",
               (driver("a"), driver("b")), inputs=(("wMarker", f"WORD#16#{UNICOS_MARKER:04X}"),)),
]
BY_NAME = {i.name: i for i in IMAGES}


def status_words(name: str) -> dict[str, int]:
    """{member: %MW} of chain program `name`'s status words (member k at %MW 100 + k)."""
    return {m: STATUS_BASE + k for k, m in enumerate(members(BY_NAME[name].status))}


def _range_image(r: Range, located: list, copy_in: list, copy_out: list):
    names = {}                                   # address -> its located variable
    def one(var, member, d, addr):
        typ = "BOOL" if addr[2] == "X" else "WORD"
        if addr not in names:
            names[addr] = var
            located.append(f"  {var} AT {addr} : {typ};")
        (copy_in if d == "in" else copy_out).append(
            f"{r.glob}.{member} := {names[addr]};" if d == "in" else f"{names[addr]} := {r.glob}.{member};")
    for m, d, base, n in r.arrays:
        for i in range(n):
            one(f"{r.glob}_{m}{i}", f"{m}[{i}]", d, _plus(base, i))
    for m, d, addr in r.words:
        one(f"{r.glob}_{m}", m, d, addr)


def generate(img: ChainImage, source: str = "plc/mipprograms/image_chain.py") -> str:
    """plc/image/<name>_io.st for chain program `img`."""
    lay = I.Image(img.name, img.program, img.instance, 1).glue
    I.glue.check(lay, "plcrt")
    head = [f"(* generated by plc/gen_programs.py from {source} and the types in plc/PLC_SoeChain.st;",
            f"   do not edit. The located image of {img.program}Logic (plc/{img.name}.st, written by",
            "   hand): the located words, copied into its structures before the call and out of them",
            "   after it. *)"]
    located, copy_in, copy_out = [], [], []
    I.params_image(members("PLC_T_SoeParams"), located, copy_in)
    I.modem_image(lay, 1, located, copy_in, copy_out)
    for r in img.ranges:
        _range_image(r, located, copy_in, copy_out)
    for m, addr in status_words(img.name).items():          # %MW100..: all written
        located.append(f"  st_{m} AT %MW{addr} : WORD;")
        copy_out.append(f"st_{m} := st.{m};")
    structs = ([("par", "PLC_T_SoeParams"), ("m1", "PLC_T_Modem")]
               + [(r.glob, r.typ) for r in img.ranges] + [("st", img.status)])
    return I.program_text(head, img.program, img.instance, structs, located, copy_in, copy_out,
                          img.inputs)
