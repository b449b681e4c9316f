"""MIP_SoeReader in a soft-PLC through the runtime's Modbus client (plcrt's trigger policy):
the program below reads 26 registers at 40601 and writes SOE_Control, as an outstation PLC
next to a relay would (docs/chain.md "The reader"). Against the C relay in the co-simulation
(the runtime's in-process transport, virtual time) and, in real time, against
`mip-emulator --relay` over Modbus TCP."""
import subprocess
from pathlib import Path

import pytest

from mipcosim.programs import lib_sources
from mipcosim.relay import Relay, RelayKernel
from miptest.soe import Entry, expected, script
from mipprograms.common import config as st_config
from plcharness import Plc
from plcharness.config import Config
from plcharness.procs import free_port, wait_port

REPO = Path(__file__).resolve().parents[2]

ORIGIN = 1767225600000
LOG = 64            # entries the program's log holds

PROGRAM = """PROGRAM MAIN
VAR
  rdr : MIP_SoeReader;
  aSoe : MIP_T_SoeRegs;
  aLog : ARRAY[0..511] OF WORD;   (* 8 words per entry *)
  uLogN : UINT;
  xStored : BOOL;
  i : UINT;
END_VAR
VAR
  rdTrig AT %QX0.0 : BOOL;
  rdDone AT %IX0.0 : BOOL;
  rdErr AT %IX0.1 : BOOL;
  rdStatus AT %IW10 : WORD;
  wrTrig AT %QX0.1 : BOOL;
  wrDone AT %IX0.2 : BOOL;
  wrErr AT %IX0.3 : BOOL;
  wrLen AT %QW1 : WORD;
  wrVal AT %QW100 : WORD;
""" + "".join(f"  r{i} AT %IW{100 + i} : WORD;\n" for i in range(26)) + """END_VAR
""" + "".join(f"aSoe[{i}] := r{i};\n" for i in range(26)) + """
rdr(xEnable := TRUE, xLoggerFull := uLogN >= 64, xEntryStored := xStored,
    aRead := aSoe, xReadValid := rdDone, xReadError := rdErr, wReadStatus := rdStatus,
    xWriteDone := wrDone, xWriteError := wrErr);
xStored := FALSE;
IF rdr.xEntryValid AND uLogN < 64 THEN
  i := uLogN * 8;
  aLog[i] := rdr.wTypeBit;
  aLog[i + 1] := rdr.wAddress;
  aLog[i + 2] := rdr.wCauseType;
  aLog[i + 3] := rdr.wValue;
  aLog[i + 4] := rdr.wTime0;
  aLog[i + 5] := rdr.wTime1;
  aLog[i + 6] := rdr.wTime2;
  aLog[i + 7] := rdr.wTime3;
  uLogN := uLogN + 1;
  xStored := TRUE;
END_IF;
rdTrig := NOT (rdDone OR rdErr);   (* free-running reads (st_lib/README.md "Wiring") *)
wrTrig := rdr.xWriteReq;
wrLen := 1;
wrVal := rdr.wWriteValue;
END_PROGRAM
""" + st_config("MAIN", "inst0")


def config(port):
    """plcrt config: device `relay`, SOE_Control written with FC16 of one register at 40602,
    the 26 registers read at 40601 (PDU addresses 601, 600)."""
    cfg = Config()
    cfg.add("master", timeout="500ms", reconnect_min="100ms", reconnect_max="1s")
    cfg.add("device", "relay", host="127.0.0.1", port=port, unit_id=1)
    cfg.add("write", "soe_control", device="relay", start=601, size=1, image="%QW100",
            policy="trigger", trigger="%QX0.1", done="%IX0.2", error="%IX0.3", length="%QW1")
    cfg.add("read", "soe", device="relay", start=600, size=26, image="%IW100", policy="trigger",
            trigger="%QX0.0", done="%IX0.0", error="%IX0.1", status="%IW10")
    return cfg.text()


def build(tmp_path, port):
    prog = tmp_path / "soe_main.st"
    prog.write_text(PROGRAM)
    conf = tmp_path / "soe.conf"
    conf.write_text(config(port))
    return Plc.build(lib_sources() + [str(prog)], workdir=tmp_path / "b",
                     compiler="stc", config=str(conf))


def logged(plc):
    n = plc["MAIN.ULOGN"]
    out = []
    for k in range(n):
        w = [plc[f"MAIN.ALOG[{8 * k + j}]"] for j in range(8)]
        out.append(Entry(w[0], w[1], w[2], w[3], w[4] << 48 | w[5] << 32 | w[6] << 16 | w[7]))
    return out


def test_soe_reader_in_a_plc_against_the_c_relay_in_cosim(tmp_path):
    events = script(20, start_s=0.1, every_s=0.037)
    plc = build(tmp_path, 1)         # the port is never used: the transport is in process
    kernel = RelayKernel()
    relay = Relay(events, kernel=kernel, origin_ms=ORIGIN)
    pid = kernel.add_plc(plc)
    relay.connect(pid, plc, "relay")
    kernel.run(3 * 10**9)
    assert logged(plc) == expected(events, ORIGIN)
    st = relay.stats()
    assert st["entries"] == 0 and st["acknowledged"] == 20 and st["bad_acks"] == 0
    assert plc["MAIN.RDR.XCAUGHTUP"] and not plc["MAIN.RDR.XERROR"]


def test_generated_events_follow_virtual_time(tmp_path):
    """The relay's generated source (rate) runs on the kernel's clock: 5 events/s for 4 s of
    virtual time are 20 entries, each time stamp origin + n x 200 ms."""
    plc = build(tmp_path, 1)
    kernel = RelayKernel()
    relay = Relay(kernel=kernel, origin_ms=ORIGIN, rate=5.0)
    relay.connect(kernel.add_plc(plc), plc, "relay")
    kernel.run(4 * 10**9 + 100 * 10**6)
    log = logged(plc)
    assert relay.stats()["generated"] == len(log) >= 20
    stamps = [e.time_ms - ORIGIN for e in log]
    assert stamps == sorted(stamps) and all(b - a == 200 for a, b in zip(stamps, stamps[1:]))
    assert [e.value for e in log] == list(range(1, len(log) + 1))   # docs/chain.md: value n + 1


@pytest.mark.slow
def test_soe_reader_in_real_time_against_mip_emulator_relay(tmp_path):
    """The runtime in real time, Modbus TCP to `mip-emulator --relay` (its wall clock)."""
    events = script(9, start_s=0.3, every_s=0.05)
    scr = tmp_path / "events.txt"
    scr.write_text("".join(f"{t:.3f} " + " ".join(f"{w:#06x}" for w in ws) + "\n"
                           for t, ws in events))
    port = free_port()
    emu = subprocess.Popen([str(REPO / "build" / "emulator" / "mip-emulator"), "--relay",
                            f"{port}:origin={ORIGIN},script={scr}"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        wait_port(port, timeout=5)
        plc = build(tmp_path, port)
        plc.run_realtime(200)        # 2 s
        got = logged(plc)
    finally:
        emu.terminate()
        out = emu.communicate(timeout=5)[0]
    # the relay stamps with its own clock from its start; values and order are exact
    exp = expected(events, ORIGIN)
    assert [(e.type_bit, e.address, e.cause_type, e.value) for e in got] == \
        [(e.type_bit, e.address, e.cause_type, e.value) for e in exp], out
    assert [e.time_ms for e in got] == [e.time_ms for e in exp], out
    assert plc["MAIN.RDR.XCAUGHTUP"] and not plc["MAIN.RDR.XERROR"]
