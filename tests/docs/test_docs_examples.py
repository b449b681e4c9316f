"""The portable wiring example of docs/wiring.md (docs/examples/glue_outstation.st) translates
with stc against st_lib, and it works: served by a minimal Modbus client against the emulator
core of the co-simulation kernel, it sends its 1000 registers to a MIP_Receiver (in a soft PLC
with the runtime's Modbus master, docs/tools/chainsim.py), register for register."""
import ctypes
import struct
import subprocess

from docs_helpers import KERNEL_SO, REPO
from mipcosim.programs import LIB_FILES

SRC = REPO / "docs" / "examples" / "glue_outstation.st"
LIB = LIB_FILES


def test_glue_example_translates(tmp_path):
    r = subprocess.run([str(REPO / ".venv" / "bin" / "stc"), "-I", str(REPO / "st_lib" / "core"),
                        "-o", str(tmp_path / "gen"), str(SRC)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "gen" / "POUS.c").exists()


class Client:
    """A minimal Modbus client (the family's client blocks in the example): one request ADU to
    the kernel's emulator core at the kernel's current time, the response parsed."""

    def __init__(self, chain, ep, unit):
        self.lib, self.net = chain.kernel.lib, chain.kernel.net
        self.ep, self.unit, self.tid = ep, unit, 0
        self.out = ctypes.create_string_buffer(400)

    def request(self, pdu):
        self.tid = (self.tid + 1) & 0xFFFF
        frame = struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, self.unit) + pdu
        n = self.lib.mipemu_handle(self.net, self.ep, frame, len(frame), self.out, 400)
        assert n > 8, "the emulator closed the connection"
        resp = self.out.raw[:n]
        return (None, resp[8]) if resp[7] & 0x80 else (resp[8:], 0)

    def read(self, addr, qty):
        body, exc = self.request(struct.pack(">BHH", 3, addr, qty))
        return (list(struct.unpack(f">{qty}H", body[1:1 + 2 * qty])), 0) if body else (None, exc)

    def write(self, addr, regs):
        pdu = struct.pack(f">BHHB{len(regs)}H", 16, addr, len(regs), 2 * len(regs), *regs)
        return self.request(pdu)[1]


def test_glue_example_sends_its_data(tmp_path):
    assert KERNEL_SO.exists(), f"{KERNEL_SO} missing: run `make {KERNEL_SO.relative_to(REPO)}`"
    from plcharness import Plc
    from mipdocs.chainsim import MS, Chain, Side

    glue = Plc.build([str(REPO / "st_lib" / f) for f in LIB] + [str(SRC)], workdir=tmp_path,
                     compiler="stc")
    # the central: chain_main.st with the runtime's master, in the co-simulation kernel; the
    # glue program scans in the same lockstep, its two requests served by the client below
    central = Side("central", "receiver", timeout_ms=1000, read_ms=100, read_phase_ms=50)
    ch = Chain(tmp_path / "chain", None, central, loss_up=0.1, loss_down=0.1, seed=5)
    ch.add_plc(glue)
    trm = Client(ch, 1, 1)
    g = "GlueOutstation."
    read_pending = write_pending = False
    block = []
    while ch.t < 120_000 * MS and not (central.transfers and glue[g + "snd.xDone"]):
        # the "Modbus client": requests started in the last scan are answered before this one
        glue[g + "xRdDone"] = False
        glue[g + "xWrDoneIn"] = False
        glue[g + "xWrErrorIn"] = False
        if read_pending:
            regs, exc = trm.read(2198, 125)
            assert exc == 0
            glue[g + "aRd"] = regs
            glue[g + "xRdDone"] = True
            read_pending = False
        if write_pending:
            exc = trm.write(2001, block)
            glue[g + "xWrDoneIn"] = exc == 0
            glue[g + "xWrErrorIn"] = exc != 0
            write_pending = False
        glue[g + "xRdBusy"] = read_pending
        glue[g + "xWrBusy"] = write_pending
        glue[g + "xStart"] = ch.t >= 100 * MS
        ch.step()
        if glue[g + "xRdStart"] and not read_pending:
            read_pending = True
        if glue[g + "xWrStart"]:
            block = glue[g + "aWr"][:glue[g + "uWrLen"]]
            write_pending = True
    ch.close()
    assert central.transfers == [list(range(1000))]
    assert central.errors == []
    assert glue[g + "snd.xDone"]
