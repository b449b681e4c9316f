"""Each protocol fact of st_lib is written once (issue 29): the echo's magic word, the
read-status bits and the check value's step are functions (MIP_Internal_EchoMagic.st, MIP_Internal_StatusBit.st,
MIP_Internal_CheckStep.st), the buffer bound a VAR CONSTANT that matches MIP_T_Buffer. A second copy
in another block would make the two drift apart in a later edit."""
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
LIB = sorted((REPO / "st_lib").glob("*/*.st"))


def code(path):
    """The ST text without comments."""
    return re.sub(r"\(\*.*?\*\)", " ", path.read_text(), flags=re.S)


def places(pattern):
    return [(p.name, m.group()) for p in LIB for m in re.finditer(pattern, code(p), re.I)]


def test_echo_magic_is_written_once():
    assert places(r"16#4D50") == [("MIP_Internal_EchoMagic.st", "16#4D50")]


def test_read_status_bits_are_decoded_in_one_place():
    # a mask applied to the read-status register (or to aRead[0]) outside the functions
    masks = places(r"\(\s*(?:wStatus|aRead\[0\])\s+AND\s+[\w#]+\s*\)")
    assert masks == [("MIP_Internal_StatusBit.st", "(wStatus AND wMask)")], masks
    # bit 4 (unconfirmed) is the one mask no other register of the library uses
    assert [f for f, _ in places(r"16#10\b")] == ["MIP_Internal_StatusBit.st"]


def test_check_value_step_is_written_once():
    # the step c := ROL(c XOR r, 5) of PROTOCOL.md's check value: only MIP_Internal_CheckStep rotates,
    # and the sender and the receiver (through MIP_Internal_ReadCheck) both fold it
    assert places(r"\bRO[LR]\s*\(") == [("MIP_Internal_CheckStep.st", "ROL(")]
    callers = sorted({f for f, _ in places(r"\bMIP_Internal_CheckStep\s*\(")} - {"MIP_Internal_CheckStep.st"})
    assert callers == ["MIP_Internal_ReadCheck.st", "MIP_Sender.st"]


def test_buffer_bound_matches_the_buffer_type():
    from mipdocs import stdecl
    types = {t.name: t for t in stdecl.parse_file(str(REPO / "st_lib" / "core" / "MIP_Types.st")).types}
    (lo, hi), = types["MIP_T_Buffer"].spec.dims
    unit = stdecl.parse_file(str(REPO / "st_lib" / "core" / "MIP_BufferSender.st"))
    consts = {v.name: v.init for p in unit.pous for s in p.sections if s.constant for v in s.vars}
    assert int(consts["udiBufferLen"]) == int(hi) - int(lo) + 1
    # the VAR CONSTANT is the one place of the number (MIP_T_Buffer says 0..8191)
    assert places(r"\b8192\b") == [("MIP_BufferSender.st", "8192")]
