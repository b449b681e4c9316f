"""A program compiled by matiec (iec2c) links with the runtime and runs in virtual time."""
from plcharness import Plc, PlcError
import pytest

from rt_helpers import needs_matiec, one_task

PROG = one_task("""
TYPE E_St : (IDLE, BUSY); END_TYPE
FUNCTION_BLOCK FB_Count
VAR_INPUT xIn : BOOL; END_VAR
VAR_OUTPUT xBusy : BOOL; cnt : UINT; END_VAR
VAR st : E_St; t1 : TON; END_VAR
IF xIn THEN cnt := cnt + 1; st := BUSY; ELSE st := IDLE; END_IF;
t1(IN := xIn, PT := T#50ms);
xBusy := t1.Q;
END_FUNCTION_BLOCK
PROGRAM MAIN
VAR inw AT %IW100 : WORD; outw AT %QW100 : WORD; bit AT %QX0.1 : BOOL; END_VAR
VAR sender : FB_Count; run : BOOL; x : INT; END_VAR
sender(xIn := run);
x := x + 1;
outw := inw;
bit := sender.xBusy;
END_PROGRAM
""")


@needs_matiec
def test_matiec_program_links_and_runs(st_file, tmp_path):
    plc = Plc.build([st_file(PROG)], workdir=tmp_path, compiler="matiec")
    assert plc.tick_ns == 10_000_000
    plc.scan(3)
    assert plc["MAIN.x"] == 3
    assert plc.time_ns == 30_000_000
    # located input to output through the program
    plc["%IW100"] = 0xBEEF
    plc.scan()
    assert plc["%QW100"] == 0xBEEF
    assert plc["instance0.outw"] == 0xBEEF
    # a TON in an FB runs on __CURRENT_TIME: 50 ms = 5 scans after run goes TRUE
    plc["MAIN.run"] = True
    plc.scan(5)
    assert plc["MAIN.sender.xBusy"] is False
    plc.scan(2)
    assert plc["main.SENDER.XBUSY"] is True
    assert plc["%QX0.1"] is True
    assert plc["MAIN.sender.st"] == 1          # BUSY
    assert plc["MAIN.sender.t1.ET"] == 50_000_000


@needs_matiec
def test_matiec_force_holds_value(st_file, tmp_path):
    plc = Plc.build([st_file(PROG)], workdir=tmp_path, compiler="matiec")
    plc.force("MAIN.x", 100)
    plc.scan(5)
    assert plc["MAIN.x"] == 100
    plc.unforce("MAIN.x")
    plc.scan(2)
    assert plc["MAIN.x"] == 102


@needs_matiec
def test_matiec_compile_error_names_the_file_and_line(st_file, tmp_path):
    src = st_file("PROGRAM MAIN\nVAR x : INT; END_VAR\nx := x + UINT#1;\nEND_PROGRAM\n", "bad.st")
    with pytest.raises(Exception) as ei:
        Plc.build([src], workdir=tmp_path, compiler="matiec")
    assert f"{src}:3:" in str(ei.value)
