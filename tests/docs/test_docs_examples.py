"""The portable wiring example of docs/wiring.md (docs/examples/glue_outstation.st) translates
with stc against st_lib, and it works: served by a minimal Modbus client against the emulator
core, it sends its 1000 registers to a MIP_Receiver, register for register."""
import subprocess

from docs_helpers import EMU_SO, REPO
from mipcosim.layout import LIB_FILES

SRC = REPO / "docs" / "examples" / "glue_outstation.st"
LIB = LIB_FILES


def test_glue_example_translates(tmp_path):
    r = subprocess.run([str(REPO / ".venv" / "bin" / "stc"), "-I", str(REPO / "st_lib"),
                        "-o", str(tmp_path / "gen"), str(SRC)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "gen" / "POUS.c").exists()


def test_glue_example_sends_its_data(tmp_path):
    assert EMU_SO.exists(), f"{EMU_SO} missing: run `make {EMU_SO.relative_to(REPO)}`"
    from plcharness import Plc
    from chainsim import MS, Side, build_plc
    from gen_traces import WORK
    from mipemu_ctypes import Net

    glue = Plc.build([str(REPO / "st_lib" / f) for f in LIB] + [str(SRC)], workdir=tmp_path,
                     compiler="stc")
    net = Net(stations=1, loss_up=0.1, loss_down=0.1, seed=5)
    central = Side("central", "receiver", timeout_ms=1000, read_ms=100, read_phase_ms=50)
    central.attach(build_plc(WORK), net, lambda *a: None)
    g = "GlueOutstation."
    read_pending = write_pending = False
    block = []
    t = 0
    while t < 120_000 * MS and not (central.transfers and glue[g + "snd.xDone"]):
        net.advance(t)
        # the "Modbus client": requests started in the last scan are answered before this one
        glue[g + "xRdDone"] = False
        glue[g + "xWrDoneIn"] = False
        glue[g + "xWrErrorIn"] = False
        if read_pending:
            regs, exc = net.read(1, 1, 2198, 125)
            assert exc == 0
            glue[g + "aRd"] = regs
            glue[g + "xRdDone"] = True
            read_pending = False
        if write_pending:
            exc = net.write(1, 1, 2001, block)
            glue[g + "xWrDoneIn"] = exc == 0
            glue[g + "xWrErrorIn"] = exc != 0
            write_pending = False
        glue[g + "xRdBusy"] = read_pending
        glue[g + "xWrBusy"] = write_pending
        glue[g + "xStart"] = t >= 100 * MS
        central.before_scan(t)
        glue.scan()
        central.plc.scan()
        central.after_scan(t)
        if glue[g + "xRdStart"] and not read_pending:
            read_pending = True
        if glue[g + "xWrStart"]:
            block = glue[g + "aWr"][:glue[g + "uWrLen"]]
            write_pending = True
        t += 10 * MS
    net.close()
    assert central.transfers == [list(range(1000))]
    assert central.errors == []
    assert glue[g + "snd.xDone"]
