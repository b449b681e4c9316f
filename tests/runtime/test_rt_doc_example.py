"""The example test of docs/runtime-harness.md, verbatim, so the page stays true."""
from miptest.rt import one_task
from plcharness import Plc

PROG = one_task("""
PROGRAM MAIN
VAR
  xStart : BOOL;
  tWait  : TON;
  nCount : UINT;
END_VAR
VAR
  wOut AT %QW100 : WORD;
END_VAR
tWait(IN := xStart, PT := T#100ms);
IF tWait.Q THEN nCount := nCount + 1; END_IF;
wOut := UINT_TO_WORD(nCount);
END_PROGRAM
""")


def test_timer_fires_after_100ms_of_virtual_time(tmp_path):
    src = tmp_path / "prog.st"
    src.write_text(PROG)
    plc = Plc.build([src], workdir=tmp_path)    # compiler="auto": stc
    plc["MAIN.xStart"] = True
    plc.scan(10)                                # 10 scans of 10 ms
    assert plc.time_ns == 100_000_000
    assert plc["MAIN.nCount"] == 0              # TON.Q comes in the scan after PT
    plc.scan()
    assert plc["MAIN.nCount"] == 1
    assert plc["%QW100"] == 1                   # located address
    plc.force("MAIN.xStart", False)             # held before and after every scan
    plc.scan(3)
    assert plc["MAIN.nCount"] == 1
