"""unit_id = %QWn: one Modbus client for many stations behind the MDP-810, the program choosing
the unit id (station address) of each request. An ST program walks the stations through one
[device] with one write and one read range, against the real mip-emulator; its trace shows the
unit id every request arrived with."""
import pytest

from miptest.emu import Emulator
from plcharness import Plc
from miptest.rt import REPO, compiler_param, one_task, read_write_ranges, tcp_device

EMU = REPO / "build" / "emulator" / "mip-emulator"

# Station by station (units 1, 2, 3; 4 is no station of a 3-station network; 300 is no unit id):
# write 1000 + i to the station's first write register, then read it back; the handshake of
# each range is the level handshake (trigger up, done or error, trigger down, both clear).
PROG = one_task("""
PROGRAM MAIN
VAR
  wUnit AT %QW40 : WORD;
  wData AT %QW41 : WORD;
  xRd AT %QX1.0 : BOOL;
  xWr AT %QX1.1 : BOOL;
  xRdDone AT %IX1.0 : BOOL;
  xRdErr AT %IX1.1 : BOOL;
  xWrDone AT %IX1.2 : BOOL;
  xWrErr AT %IX1.3 : BOOL;
  wRdStatus AT %IW11 : WORD;
  wWrStatus AT %IW21 : WORD;
  wRd AT %IW100 : WORD;
END_VAR
VAR
  aUnit : ARRAY[1..5] OF WORD := [1, 2, 3, 4, 300];
  aRead : ARRAY[1..5] OF WORD;
  aRdStatus : ARRAY[1..5] OF WORD;
  aWrStatus : ARRAY[1..5] OF WORD;
  i : INT := 1;
  nStep : INT;
  xFinished : BOOL;
END_VAR
CASE nStep OF
0:  wUnit := aUnit[i];
    wData := INT_TO_WORD(1000 + i);
    xWr := TRUE;
    IF xWrDone OR xWrErr THEN
      aWrStatus[i] := wWrStatus;
      xWr := FALSE;
      wUnit := 0;                (* the request has its unit id: the word is free again *)
      nStep := 1;
    END_IF;
1:  IF NOT (xWrDone OR xWrErr) THEN
      wUnit := aUnit[i];
      xRd := TRUE;
      nStep := 2;
    END_IF;
2:  IF xRdDone OR xRdErr THEN
      aRead[i] := wRd;
      aRdStatus[i] := wRdStatus;
      xRd := FALSE;
      nStep := 3;
    END_IF;
3:  IF NOT (xRdDone OR xRdErr) THEN
      IF i = 5 THEN xFinished := TRUE; nStep := 4; ELSE i := i + 1; nStep := 0; END_IF;
    END_IF;
END_CASE;
END_PROGRAM
""")

def config(port) -> str:
    """The MDP as one device whose unit id the program sets (%QW40), with [read rd] and
    [write wr] of one register at 10 (miptest.rt.read_write_ranges)."""
    return read_write_ranges("mdp", 10, tcp_device(port, "mdp", unit_id="%QW40", timeout="2s",
                                                   errors="%IW30"))


@pytest.fixture
def mdp(tmp_path):
    if not EMU.exists():
        pytest.fail(f"{EMU} is missing: run `make` first", pytrace=False)
    emu = Emulator("--stations", "3", trace=tmp_path / "emu.jsonl")

    def stop():
        """stops the emulator; its MDP requests in order (the trace is complete at exit)"""
        emu.stop()
        return [e for e in emu.trace() if e["ev"] == "modbus" and e["ep"] == "mdp"]

    yield emu.mdp_port, stop
    emu.stop()


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_program_chooses_the_station_of_each_request(compiler, mdp, tmp_path):
    port, stop = mdp
    cfg = tmp_path / "central.conf"
    cfg.write_text(config(port))
    src = tmp_path / "prog.st"
    src.write_text(PROG)
    plc = Plc.build([src], workdir=tmp_path, compiler=compiler, config=cfg)
    for _ in range(100):
        plc.scan()
        if plc["MAIN.xFinished"]:
            break
    assert plc["MAIN.xFinished"]
    # stations 1..3 each got their own value and gave it back
    assert [plc[f"MAIN.aWrStatus[{i}]"] for i in range(1, 6)] == [0, 0, 0, 11, 1022]
    assert [plc[f"MAIN.aRdStatus[{i}]"] for i in range(1, 6)] == [0, 0, 0, 11, 1022]
    assert [plc[f"MAIN.aRead[{i}]"] for i in range(1, 4)] == [1001, 1002, 1003]
    # 4: the MDP's answer for no such station (0B); 300: not sent, 1000 + EINVAL, counted
    assert plc["%IW30"] == 4
    requests = stop()
    assert [(e["unit"], e["fc"]) for e in requests] == [
        (1, 16), (1, 3), (2, 16), (2, 3), (3, 16), (3, 3), (4, 16), (4, 3)]
    assert [e["exc"] for e in requests] == [0] * 6 + [11, 11]
    plc.close()
