"""The plcharness API (docs/dev/interfaces.md §5) on programs built by stc and by matiec."""
import pytest

from plcharness import BuildError, Plc, PlcError
from miptest.rt import COMPILERS, compiler_param, one_task

PROG = one_task("""
TYPE E_State : (ST_IDLE, ST_BUSY); END_TYPE
FUNCTION_BLOCK FB_Count
VAR_INPUT xIn : BOOL; END_VAR
VAR_OUTPUT xBusy : BOOL; cnt : UINT; tEt : TIME; END_VAR
VAR eState : E_State; tDelay : TON; END_VAR
IF xIn THEN cnt := cnt + 1; eState := ST_BUSY; ELSE eState := ST_IDLE; END_IF;
tDelay(IN := xIn, PT := T#50ms);
xBusy := tDelay.Q;
tEt := tDelay.ET;
END_FUNCTION_BLOCK
PROGRAM MAIN
VAR inw AT %IW100 : WORD; outw AT %QW100 : WORD; bit AT %QX0.1 : BOOL; flag AT %IX2.3 : BOOL; END_VAR
VAR sender : FB_Count; run : BOOL; x : INT; big : DINT; tElapsed : TIME; END_VAR
sender(xIn := run);
x := x + 1;
outw := inw;
bit := sender.xBusy;
IF flag THEN big := big + 100000; END_IF;
tElapsed := sender.tEt;
END_PROGRAM
""")


@pytest.fixture(params=COMPILERS)
def plc(request, st_file, tmp_path):
    return Plc.build([st_file(PROG)], workdir=tmp_path, compiler=request.param)


def test_scan_advances_virtual_time_by_the_task_tick(plc):
    assert plc.time_ns == 0
    plc.scan()
    assert plc.time_ns == 10_000_000
    plc.scan(99)
    assert plc.time_ns == 1_000_000_000
    assert plc["MAIN.x"] == 100


def test_paths_are_case_insensitive_and_rooted_at_type_or_instance(plc):
    plc.scan(3)
    assert plc["MAIN.x"] == plc["main.X"] == plc["instance0.x"] == 3
    assert plc["CONFIG0.RES0.INSTANCE0.X"] == 3


def test_located_addresses_read_and_write_the_image(plc):
    plc["%IW100"] = 0xBEEF
    plc["%IX2.3"] = True
    plc.scan()
    assert plc["%QW100"] == 0xBEEF
    assert plc["MAIN.outw"] == 0xBEEF
    assert plc["MAIN.big"] == 100000
    assert plc["MAIN.flag"] is True


def test_fb_outputs_timers_and_enums(plc):
    plc["MAIN.run"] = True
    plc.scan(5)
    assert plc["MAIN.sender.xBusy"] is False
    assert plc["MAIN.sender.eState"] == 1  # ST_BUSY
    plc.scan(2)
    assert plc["MAIN.sender.xBusy"] is True
    assert plc["%QX0.1"] is True
    assert plc["MAIN.tElapsed"] == 50_000_000  # TIME reads as int ns
    assert plc["MAIN.sender.cnt"] == 7


def test_write_takes_effect_next_scan_and_program_may_overwrite(plc):
    plc.scan()
    plc["MAIN.x"] = 1000
    assert plc["MAIN.x"] == 1000
    plc.scan()
    assert plc["MAIN.x"] == 1001


def test_force_holds_until_unforced(plc):
    plc.force("MAIN.x", 5)
    plc.scan(10)
    assert plc["MAIN.x"] == 5
    plc.force("%IW100", 7)
    plc["%IW100"] = 1
    plc.scan()
    assert plc["%QW100"] == 7
    plc.unforce("MAIN.x")
    plc.unforce("%IW100")
    plc.scan()
    assert plc["MAIN.x"] == 6
    with pytest.raises(PlcError, match="not forced"):
        plc.unforce("MAIN.x")


def test_bad_names_and_values_are_clear_errors(plc):
    with pytest.raises(PlcError, match="no variable 'MAIN.nothing'"):
        plc["MAIN.nothing"]
    with pytest.raises(PlcError, match="outside the image"):
        plc["%IW1024"]
    with pytest.raises(PlcError, match="out of range for INT"):
        plc["MAIN.x"] = 40000
    with pytest.raises(PlcError, match="out of range for WORD"):
        plc["%QW100"] = -1
    with pytest.raises(PlcError, match="BOOL"):
        plc["MAIN.run"] = 2


def test_real_time_scans_run_the_program(plc):
    stats = plc.run_realtime(5)
    assert stats["scans"] == 5
    assert plc["MAIN.x"] == 5
    with pytest.raises(PlcError, match="real-time"):
        plc.scan()


ARRAYS = one_task("""
TYPE T_Buf : ARRAY[0..3] OF WORD; END_TYPE
PROGRAM MAIN
VAR buf : T_Buf; grid : ARRAY[1..2, 1..3] OF INT; sum : UINT; i : INT; END_VAR
sum := 0;
FOR i := 0 TO 3 DO sum := sum + WORD_TO_UINT(buf[i]); END_FOR;
grid[2, 3] := grid[2, 3] + 1;
END_PROGRAM
""", "T#20ms")


@pytest.mark.parametrize("compiler", COMPILERS)
def test_arrays_read_as_lists_and_by_element(compiler, st_file, tmp_path):
    # (with matiec the array rows come from stc's table of the same sources)
    plc = Plc.build([st_file(ARRAYS)], workdir=tmp_path, compiler=compiler)
    plc["MAIN.buf"] = [1, 2, 3, 4]
    plc["MAIN.buf[3]"] = 40
    plc.scan(2)
    assert plc["MAIN.buf"] == [1, 2, 3, 40]
    assert plc["MAIN.sum"] == 46
    assert plc["MAIN.grid"] == [[0, 0, 0], [0, 0, 2]]
    assert plc["MAIN.grid[2,3]"] == 2
    with pytest.raises(PlcError, match="index 4 outside 0..3"):
        plc["MAIN.buf[4]"]
    assert plc.time_ns == 40_000_000


@pytest.mark.parametrize("compiler", COMPILERS)
def test_two_plcs_of_one_program_do_not_share_state(compiler, st_file, tmp_path):
    src = st_file(PROG)
    a = Plc.build([src], workdir=tmp_path / "a", compiler=compiler)
    b = Plc.build([src], workdir=tmp_path / "b", compiler=compiler)
    a.scan(3)
    b.scan(1)
    assert (a["MAIN.x"], b["MAIN.x"]) == (3, 1)


@pytest.mark.parametrize("compiler", COMPILERS)
def test_translation_error_is_reported(compiler, st_file, tmp_path):
    src = st_file("PROGRAM MAIN\nVAR x : INT; END_VAR\nx := x + UINT#1;\nEND_PROGRAM\n", "bad.st")
    with pytest.raises(BuildError) as ei:
        Plc.build([src], workdir=tmp_path, compiler=compiler)
    assert f"{src}:3:" in str(ei.value)


@pytest.mark.parametrize("compiler", COMPILERS)
def test_program_without_a_task_is_a_clear_error(compiler, st_file, tmp_path):
    src = st_file("PROGRAM MAIN\nVAR x : INT; END_VAR\nx := x + 1;\nEND_PROGRAM\n")
    with pytest.raises((BuildError, PlcError)) as ei:
        Plc.build([src], workdir=tmp_path, compiler=compiler)
    msg = str(ei.value)
    assert "ABI" in msg or "no task" in msg, msg


STRUCTS = one_task("""
TYPE S_Point : STRUCT x : INT; tags : ARRAY[1..2] OF WORD; END_STRUCT; END_TYPE
FUNCTION_BLOCK FB_Hold
VAR_INPUT pIn : S_Point; END_VAR
VAR_OUTPUT pOut : S_Point; hist : ARRAY[0..2] OF INT; END_VAR
pOut := pIn;
hist[2] := hist[1]; hist[1] := hist[0]; hist[0] := pIn.x;
END_FUNCTION_BLOCK
PROGRAM MAIN
VAR p : S_Point; h : FB_Hold; END_VAR
p.x := p.x + 1;
h(pIn := p);
END_PROGRAM
""")


@pytest.mark.parametrize("compiler", COMPILERS)
def test_struct_members_and_fb_arrays(compiler, st_file, tmp_path):
    plc = Plc.build([st_file(STRUCTS)], workdir=tmp_path, compiler=compiler)
    plc["MAIN.p.tags"] = [7, 8]
    plc.scan(3)
    assert plc["MAIN.p.x"] == 3
    assert plc["MAIN.h.pOut.x"] == 3
    assert plc["MAIN.h.pOut.tags"] == [7, 8]
    assert plc["MAIN.h.hist"] == [3, 2, 1]


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_c_level_access_for_cosimulation(compiler, st_file, tmp_path):
    import ctypes
    plc = Plc.build([st_file(PROG)], workdir=tmp_path, compiler=compiler)
    ctypes.c_int16.from_address(plc.address("MAIN.x")).value = 41
    lib = plc.library
    lib.plcrt_scan(plc.handle, 1)
    assert plc["MAIN.x"] == 42
    assert plc.address("%QW100") != plc.address("%IW100")


@pytest.mark.parametrize("compiler", COMPILERS)
def test_a_located_variable_outside_the_image_stops_the_load_in_one_line(st_file, tmp_path,
                                                                       compiler):
    """The glue binds every line of LOCATED_VARIABLES.h in order; the first one the image has no
    room for is named, with its address and the limit (runtime_shim/README.md)."""
    src = st_file(one_task("""
PROGRAM MAIN
VAR a AT %IW3 : WORD; b AT %QX1.2 : BOOL; c AT %MD5 : DINT; far AT %IW1500 : WORD; END_VAR
a := a;
END_PROGRAM
"""))
    with pytest.raises(PlcError) as e:
        Plc.build([src], workdir=tmp_path, compiler=compiler)
    assert str(e.value) == "located variable __IW1500: %IW1500: outside the image (n < 1024)"


@pytest.mark.parametrize("compiler", COMPILERS)
def test_located_variables_of_each_area_and_size_are_the_image(st_file, tmp_path, compiler):
    """What the program writes to its located variables is in the image at their addresses,
    and what is put into the image is what the program reads."""
    plc = Plc.build([st_file(one_task("""
PROGRAM MAIN
VAR a AT %IW3 : WORD; b AT %QX1.2 : BOOL; c AT %MD5 : DINT; d AT %QW7 : WORD;
    e AT %IX0.7 : BOOL; f AT %MW9 : WORD; END_VAR
d := a; b := e; c := c + 1; f := a;
END_PROGRAM
"""))], workdir=tmp_path, compiler=compiler)
    plc["%IW3"] = 0xBEEF
    plc["%IX0.7"] = True
    plc["%MD5"] = 41
    plc.scan()
    assert (plc["%QW7"], plc["%QX1.2"], plc["%MD5"], plc["%MW9"]) == (0xBEEF, True, 42, 0xBEEF)
