"""A program compiled by matiec (iec2c) links with the runtime and runs in virtual time."""
from plcharness import Plc
import pytest

from miptest.rt import needs_matiec, one_task

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


RETAINED = one_task("""
TYPE T_Block : ARRAY[0..3] OF WORD; END_TYPE
FUNCTION_BLOCK FB_Acc
VAR_INPUT inc : UINT; END_VAR
VAR_OUTPUT total : UINT; END_VAR
VAR RETAIN own : UINT; END_VAR
own := own + inc; total := own;
END_FUNCTION_BLOCK
PROGRAM MAIN
VAR RETAIN n : UINT; hist : ARRAY[1..3] OF INT; blk : T_Block; kept : FB_Acc; END_VAR
VAR lost : UINT; plain : FB_Acc; END_VAR
n := n + 1; lost := lost + 1;
hist[2] := hist[2] + 2; blk[3] := UINT_TO_WORD(WORD_TO_UINT(blk[3]) + 16);
kept(inc := 1); plain(inc := 1);
END_PROGRAM
""")


@needs_matiec
def test_matiec_build_keeps_its_retain_variables_over_a_warm_restart(st_file, tmp_path):
    """What matiec marks retained (VARIABLES.csv, __IEC_RETAIN_FLAG), the arrays it cannot
    mark, and a RETAIN variable of an FB instance in a plain VAR section survive; the rest
    starts from its initial value."""
    plc = Plc.build([st_file(RETAINED)], workdir=tmp_path / "a", compiler="matiec")
    assert plc.retain_count() > 0
    plc.scan(7)
    snapshot = plc.retain_save()
    plc.close()
    again = Plc.build([st_file(RETAINED)], workdir=tmp_path / "b", compiler="matiec")
    again.retain_load(snapshot)
    again.scan(1)
    assert again["MAIN.n"] == 8 and again["MAIN.lost"] == 1
    assert again["MAIN.hist"][1] == 16
    assert again["MAIN.blk"][3] == 0x80
    assert again["MAIN.kept.total"] == 8
    assert again["MAIN.plain.own"] == 8 and again["MAIN.plain.total"] == 8


MATIEC_ONLY = one_task("""
PROGRAM MAIN
VAR RETAIN n : UINT; tmr : TON; go : BOOL; END_VAR
VAR lost : UINT; END_VAR
VAR out AT %QW100 : WORD; END_VAR
n := n + 1; lost := lost + 1;
tmr(IN := go, PT := T#5s);
out := UINT_TO_WORD(n);
END_PROGRAM
""")


@needs_matiec
def test_matiec_build_without_stc_keeps_what_matiec_marks_retained(st_file, tmp_path, monkeypatch):
    """Where stc does not translate the sources (not installed, or a program only matiec
    takes), the variables matiec marks retained are kept, except a standard timer's internal
    state: its start time from before the restart would hold it for the previous uptime (the
    scan clock starts at 0); it times its 5 s anew."""
    from plcharness import build

    def no_stc(*args, **kwargs):
        raise build.BuildError("stc: cannot run stc: No such file or directory")
    monkeypatch.setattr(build, "_translate_stc", no_stc)
    monkeypatch.setenv("PLCRT_CACHE", "off")
    src = st_file(MATIEC_ONLY)
    plc = Plc.build([src], workdir=tmp_path / "a", compiler="matiec")
    assert plc.retain_count() > 0
    plc.scan(100)
    plc["MAIN.go"] = True
    plc.scan(300)                                   # the timer started at 1 s
    assert plc["MAIN.tmr.ET"] == 2_990_000_000
    snapshot = plc.retain_save()
    warm = Plc(plc.build_result, tmp_path / "a")
    warm.retain_load(snapshot)
    warm.scan(1)
    assert warm["MAIN.n"] == 401 and warm["MAIN.lost"] == 1 and warm["%QW100"] == 401
    warm.scan(499)                                  # 0 .. 4.99 s: not yet
    assert not warm["MAIN.tmr.Q"] and warm["MAIN.tmr.ET"] == 4_990_000_000
    warm.scan(1)
    assert warm["MAIN.tmr.Q"]
