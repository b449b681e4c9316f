"""The example programs (plc/outstation.st, plc/central.st) with a vendor family's glue in place
of their located I/O (their generated image plc/image/*_io.st) (issue 36; families twincat, codesys, s7): station 1's read and write go through the glue block the
release ships (dist/glue/<family>/) and the stand-ins of the vendor's client blocks
(standins/<family>/), which put each request on the wire through the runtime's request channel
(Setup(channel=True)). Everything else — logger, MIP blocks, parameters, event taps — is the
example program unchanged, so the chain's record-for-record check (check.py) applies as it is.
"""
from __future__ import annotations

import re
from pathlib import Path

from mipprobe.regmap import MDP810, TRM810

from . import programs as L

REPO = L.REPO
FAMILIES = ("twincat", "codesys", "s7")
GLUE = {"twincat": [REPO / "dist" / "glue" / "twincat" / "MIP_TcModbusIo.twincat.st"],
        "codesys": [REPO / "dist" / "glue" / "codesys" / "MIP_CdsModbusIo.codesys.st"],
        "s7": [REPO / "dist" / "glue" / "s7" / "MIP_S7ModbusIo.scl"]}
STANDINS = {"twincat": [REPO / "standins" / "StandIn_Channel.twincat.st",
                        REPO / "standins" / "twincat" / "Tc2_ModbusSrv.twincat.st"],
            "codesys": [REPO / "standins" / "StandIn_Channel.twincat.st",
                        REPO / "standins" / "codesys" / "ModbusFB.codesys.st"],
            "s7": [REPO / "standins" / "StandIn_Channel.twincat.st",
                   REPO / "standins" / "s7" / "MB_CLIENT.codesys.st"]}
# what the example program takes from the glue block (the same outputs in every family), into
# the structure PLC_T_Modem the hand-written logic reads (plc/PLC_Logger.st)
OUTPUTS = ("m{s}.xRdDone := io{s}.xReadValid;\n"
           "m{s}.aRead := io{s}.aRead;\n"
           "m{s}.xRdErr := io{s}.xReadError;\n"
           "m{s}.wRdSt := io{s}.wReadStatus;\n"
           "m{s}.xWrDone := io{s}.xWriteDone;\n"
           "m{s}.xWrErr := io{s}.xWriteError;\n")
# the glue block's call per family: station s, unit id, addresses; its request and block are the
# logic's of the last scan (m<s>.xWrTrig, .aWrite, .wWrLen); enabled while the start word is set
CALL = {"twincat": (
    "io{s}(sIPAddr := '127.0.0.1', nTCPPort := 502, nUnitID := {unit}, nReadAddr := {ra},\n"
    "    nWriteAddr := SEL(pGlueWriteAddr = WORD#0, pGlueWriteAddr, WORD#{wa}), tTimeout := T#2S,\n"
    "    xEnable := par.wStart <> 0, xWriteReq := m{s}.xWrTrig,\n"
    "    aWrite := m{s}.aWrite, uWriteLen := WORD_TO_UINT(m{s}.wWrLen));\n"
    + OUTPUTS,
    "MIP_TcModbusIo"),
    "codesys": (
    "io{s}(aIPaddr := aGlueIP, uiPort := 502, uiUnitId := {unit}, uiReadAddr := {ra},\n"
    "    uiWriteAddr := WORD_TO_UINT(SEL(pGlueWriteAddr = WORD#0, pGlueWriteAddr, WORD#{wa})),\n"
    "    xEnable := par.wStart <> 0, xWriteReq := m{s}.xWrTrig,\n"
    "    aWrite := m{s}.aWrite, uWriteLen := WORD_TO_UINT(m{s}.wWrLen));\n"
    + OUTPUTS,
    "MIP_CdsModbusIo"),
    # S7: MB_CLIENT's 4xxxx addresses (40001 + the 0-based register)
    "s7": (
    "io{s}.ipAddress[0] := 127;\nio{s}.ipAddress[3] := 1;\n"
    "io{s}(connectId := 1, unitId := {unit}, readAddr := 40001 + {ra},\n"
    "    writeAddr := SEL(pGlueWriteAddr = WORD#0, WORD_TO_UDINT(pGlueWriteAddr), UDINT#{wa}) + 40001,\n"
    "    enable := par.wStart <> 0, writeReq := m{s}.xWrTrig,\n"
    "    aWrite := m{s}.aWrite, writeLen := WORD_TO_UINT(m{s}.wWrLen));\n"
    "m{s}.xRdDone := io{s}.readValid;\n"
    "m{s}.aRead := io{s}.aRead;\n"
    "m{s}.xRdErr := io{s}.readError;\n"
    "m{s}.wRdSt := io{s}.readStatus;\n"
    "m{s}.xWrDone := io{s}.writeDone;\n"
    "m{s}.xWrErr := io{s}.writeError;\n",
    "MIP_S7ModbusIo")}


# declarations a family's call needs besides the glue block (CODESYS: the modem's address, which
# the stand-in's ClientTCP wants set: its default 255.255.255.255 never connects)
EXTRA_DECL = {"codesys": "  aGlueIP : ARRAY[0..3] OF BYTE := [127, 0, 0, 1];   (* the modem's address *)\n"}


# a parameter word of the variant programs: the glue's write address instead of the modem's
# (0: the modem's), so a test makes every write fail without another build
WRITE_ADDR_WORD = 40


class GlueError(RuntimeError):
    pass


def variant(text: str, family: str, role: str, s: int = 1) -> str:
    """The example program's generated image `text` (plc/image/<role>_io.st) with station s's
    located I/O replaced by `family`'s glue block: the located words of its modem ranges and
    their copies go, the glue's call fills the structure m<s> the hand-written logic reads."""
    call, fb_type = CALL[family]
    text, k = re.subn(rf"^  (?:[rw]{s}_\d+|m{s}_\w+) AT %[IQ][XW][\d.]+ : \w+;\n", "", text,
                      flags=re.M)
    if k != 125 + 123 + 8:
        raise GlueError(f"station {s}: {k} located modem words, expected 256")
    text, k = re.subn(rf"^(?:m{s}\.\w+(?:\[\d+\])? := (?:r{s}_\d+|m{s}_\w+)|"
                      rf"(?:w{s}_\d+|m{s}_\w+) := m{s}\.\w+(?:\[\d+\])?);\n", "", text, flags=re.M)
    if k != 125 + 123 + 8:
        raise GlueError(f"station {s}: {k} copies of the modem words, expected 256")
    head = re.search(r"^PROGRAM \w+\n", text, re.M)
    if not head:
        raise GlueError("no PROGRAM in the image")
    text = (text[:head.end()] + "VAR\n  (* the vendor glue (issue 36) *)\n"
            + f"  io{s} : {fb_type};\n" + EXTRA_DECL.get(family, "") + "END_VAR\nVAR\n"
            + f"  pGlueWriteAddr AT %MW{WRITE_ADDR_WORD} : WORD;   (* the glue's write address (0: the modem's); tests *)\n"
            + "END_VAR\n" + text[head.end():])
    m = re.search(r"^app\(", text, re.M)
    if not m:
        raise GlueError("no call of the logic (app) in the image")
    regs = TRM810 if role == "outstation" else MDP810
    unit, ra, wa = "1" if role == "outstation" else str(s), str(regs.read_status), str(regs.write_data)
    return (text[:m.start()] + f"(* station {s}: the {family} glue and the stand-ins *)\n"
            + call.format(s=s, unit=unit, ra=ra, wa=wa) + text[m.start():])


def sources(family: str, role: str, workdir: Path) -> list[str]:
    """The build's files: st_lib, the logger, the hand-written logic, the stand-ins, the glue,
    the variant image."""
    if family not in FAMILIES:
        raise GlueError(f"family {family!r}: one of {', '.join(FAMILIES)}")
    base = L.program_sources(role, False)
    main = Path(base[-1])           # the generated image (plc/image/<role>_io.st)
    out = Path(workdir) / f"{main.stem}.{'codesys' if family == 's7' else family}.st"
    out.parent.mkdir(parents=True, exist_ok=True)
    new = variant(main.read_text(), family, role)
    if not out.exists() or out.read_text() != new:
        out.write_text(new)
    return base[:-1] + [str(p) for p in STANDINS[family] + GLUE[family]] + [str(out)]
