"""The example programs (plc/outstation.st, plc/central.st) with a vendor family's glue in place
of their located I/O (issue 36; families twincat, codesys, s7): station 1's read and write go through the glue block the
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
# what the example program takes from the glue block (the same outputs in every family)
OUTPUTS = ("xRdValid{s} := io{s}.xReadValid;\n"
           "IF xRdValid{s} THEN rd{s} := io{s}.aRead; END_IF;\n"
           "rdErr{s} := io{s}.xReadError;\n"
           "rdSt{s} := io{s}.wReadStatus;\n"
           "xWrDone{s} := io{s}.xWriteDone;\n"
           "wrErr{s} := io{s}.xWriteError;\n")
# the glue block's call per family: station s, its MIP block (snd / rcv1 ...), unit id, addresses
CALL = {"twincat": (
    "io{s}(sIPAddr := '127.0.0.1', nTCPPort := 502, nUnitID := {unit}, nReadAddr := {ra},\n"
    "    nWriteAddr := SEL(pGlueWriteAddr = WORD#0, pGlueWriteAddr, WORD#{wa}), tTimeout := T#2S,\n"
    "    xEnable := xRun, xWriteReq := wrTrig{s},\n"
    "    aWrite := {blk}.aWrite, uWriteLen := {blk}.uWriteLen);\n"
    + OUTPUTS,
    "MIP_TcModbusIo"),
    "codesys": (
    "io{s}(aIPaddr := aGlueIP, uiPort := 502, uiUnitId := {unit}, uiReadAddr := {ra},\n"
    "    uiWriteAddr := WORD_TO_UINT(SEL(pGlueWriteAddr = WORD#0, pGlueWriteAddr, WORD#{wa})),\n"
    "    xEnable := xRun, xWriteReq := wrTrig{s},\n"
    "    aWrite := {blk}.aWrite, uWriteLen := {blk}.uWriteLen);\n"
    + OUTPUTS,
    "MIP_CdsModbusIo"),
    # S7: MB_CLIENT's 4xxxx addresses (40001 + the 0-based register)
    "s7": (
    "io{s}.ipAddress[0] := 127;\nio{s}.ipAddress[3] := 1;\n"
    "io{s}(connectId := 1, unitId := {unit}, readAddr := 40001 + {ra},\n"
    "    writeAddr := SEL(pGlueWriteAddr = WORD#0, WORD_TO_UDINT(pGlueWriteAddr), UDINT#{wa}) + 40001,\n"
    "    enable := xRun, writeReq := wrTrig{s},\n"
    "    aWrite := {blk}.aWrite, writeLen := {blk}.uWriteLen);\n"
    "xRdValid{s} := io{s}.readValid;\n"
    "IF xRdValid{s} THEN rd{s} := io{s}.aRead; END_IF;\n"
    "rdErr{s} := io{s}.readError;\n"
    "rdSt{s} := io{s}.readStatus;\n"
    "xWrDone{s} := io{s}.writeDone;\n"
    "wrErr{s} := io{s}.writeError;\n",
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
    """The example program `text` (role "outstation" / "central") with station s's located I/O
    replaced by `family`'s glue block."""
    call, fb_type = CALL[family]
    # the MIP block whose aWrite the write section copies
    m = re.search(rf"^  w{s}_0 := (\w+)\.aWrite\[0\];$", text, re.M)
    if not m:
        raise GlueError(f"no write section of station {s} in the program")
    blk = m.group(1)
    # the located words of station s become plain variables (or go: the glue has the data)
    names = [f"rdTrig{s}", f"rdDone{s}", f"rdErr{s}", f"rdSt{s}", f"wrTrig{s}", f"wrDone{s}",
             f"wrErr{s}", f"wrLen{s}"]
    decl = []
    for n in names:
        m = re.search(rf"^  {n} AT %\w+(?:\.\d+)? : (\w+);.*\n", text, re.M)
        if not m:
            raise GlueError(f"no located {n} in the program")
        decl.append(f"  {n} : {m.group(1)};\n")
        text = text[:m.start()] + text[m.end():]
    text, k = re.subn(rf"^  [rw]{s}_\d+ AT %\w+ : WORD;.*\n", "", text, flags=re.M)
    if k != 125 + 123:
        raise GlueError(f"station {s}: {k} located data words, expected 248")
    head = re.search(r"^PROGRAM \w+\n", text, re.M)
    text = (text[:head.end()] + "VAR\n  (* the vendor glue (issue 36) *)\n"
            + f"  io{s} : {fb_type};\n" + EXTRA_DECL.get(family, "") + "".join(decl) + "END_VAR\nVAR\n"
            + f"  pGlueWriteAddr AT %MW{WRITE_ADDR_WORD} : WORD;   (* the glue's write address (0: the modem's); tests *)\n"
            + "END_VAR\n" + text[head.end():])
    # the read section (up to the write-done line) -> the glue call
    m = re.search(rf"^\(\* station {s}: read handshake.*?^xWrDone{s} := .*?\n", text, re.M | re.S)
    if not m:
        raise GlueError(f"no read section of station {s}")
    regs = TRM810 if role == "outstation" else MDP810
    unit, ra, wa = "1" if role == "outstation" else str(s), str(regs.read_status), str(regs.write_data)
    text = (text[:m.start()] + f"(* station {s}: the {family} glue and the stand-ins *)\n"
            + call.format(s=s, unit=unit, ra=ra, wa=wa, blk=blk) + text[m.end():])
    # the write section: only the request stays (the glue takes the block at its edge)
    m = re.search(rf"^\(\* station {s}: write handshake.*?\n(wrTrig{s} := \w+\.xWriteReq;\n)"
                  rf"IF wrTrig{s} OR xCyclic THEN\n.*?^END_IF;\n", text, re.M | re.S)
    if not m:
        raise GlueError(f"no write section of station {s}")
    text = text[:m.start()] + m.group(1) + text[m.end():]
    return text


def sources(family: str, role: str, workdir: Path) -> list[str]:
    """The build's files: st_lib, the logger, the stand-ins, the glue, the variant program."""
    if family not in FAMILIES:
        raise GlueError(f"family {family!r}: one of {', '.join(FAMILIES)}")
    base = L.program_sources(role, False)
    main = Path(base[-1])
    out = Path(workdir) / f"{main.stem}.{'codesys' if family == 's7' else family}.st"
    out.parent.mkdir(parents=True, exist_ok=True)
    new = variant(main.read_text(), family, role)
    if not out.exists() or out.read_text() != new:
        out.write_text(new)
    return base[:-1] + [str(p) for p in STANDINS[family] + GLUE[family]] + [str(out)]
