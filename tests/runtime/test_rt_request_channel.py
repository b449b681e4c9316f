"""The per-request channel a vendor client block needs (issue 36): a trigger range whose first
address (`address = %QW<n>`) and quantity (`length = %QW<n>`, reads too) the program sets before
each rising edge, as FB_MBReadRegs' nMBAddr / nQuantity or MB_CLIENT's MB_DATA_ADDR /
MB_DATA_LEN. What goes on the wire is checked at a Modbus TCP server's log."""
import pytest

from plcharness import Plc, PlcError
from miptest.rt import compiler_param, one_task, tcp_device, trigger_range

PROG = one_task("""
PROGRAM MAIN
VAR
  xRd AT %QX1.0 : BOOL;
  xRdDone AT %IX1.0 : BOOL;
  xRdErr AT %IX1.1 : BOOL;
  wRdStatus AT %IW11 : WORD;
  wRdAddr AT %QW40 : WORD;
  wRdLen AT %QW41 : WORD;
  wIn0 AT %IW100 : WORD;
  wIn1 AT %IW101 : WORD;
  wIn2 AT %IW102 : WORD;
  xWr AT %QX1.1 : BOOL;
  xWrDone AT %IX1.2 : BOOL;
  xWrErr AT %IX1.3 : BOOL;
  wWrAddr AT %QW42 : WORD;
  wWrLen AT %QW43 : WORD;
  wOut0 AT %QW200 : WORD;
  wOut1 AT %QW201 : WORD;
END_VAR
VAR
  nDone : UINT;
  nErr : UINT;
  wLastStatus : WORD;
END_VAR
IF (xRd AND (xRdDone OR xRdErr)) OR (xWr AND (xWrDone OR xWrErr)) THEN
  IF xRdDone OR xWrDone THEN nDone := nDone + 1; ELSE nErr := nErr + 1; END_IF;
  IF xRd THEN wLastStatus := wRdStatus; END_IF;
  xRd := FALSE;
  xWr := FALSE;
END_IF;
END_PROGRAM
""")

def config(port, channel=True) -> str:
    """[write wr] and [read rd] of the modem with address and length from the image (channel);
    without channel, [read rd] is a cyclic read that still has an address key (a mistake)."""
    cfg = tcp_device(port, "modem", timeout="1s")
    trigger_range(cfg, "write", "wr", "modem", 0, "%QW200", ("%QX1.1", "%IX1.2", "%IX1.3"),
                  size=2, address="%QW42", length="%QW43")
    if channel:
        trigger_range(cfg, "read", "rd", "modem", 0, "%IW100", ("%QX1.0", "%IX1.0", "%IX1.1"),
                      "%IW11", size=3, address="%QW40", length="%QW41")
    else:
        cfg.add("read", "rd", device="modem", start=0, size=3, image="%IW100", policy="cycle",
                status="%IW11", address="%QW40")
    return cfg.text()


def _build(server, st_file, tmp_path, channel=True):
    cfg = tmp_path / "plc.conf"
    cfg.write_text(config(server.port, channel))
    return Plc.build([st_file(PROG)], workdir=tmp_path, compiler="stc", config=cfg)


def _request(plc, bit, **words):
    for k, v in words.items():
        plc[f"MAIN.{k}"] = v
    before = plc["MAIN.nDone"] + plc["MAIN.nErr"]
    plc[f"MAIN.{bit}"] = True
    plc.scan(4)
    assert plc["MAIN.nDone"] + plc["MAIN.nErr"] == before + 1, "the request did not end"


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_address_and_quantity_are_taken_at_each_edge(compiler, server, st_file, tmp_path):
    server.holding[198:201] = [7, 8, 9]
    plc = _build(server, st_file, tmp_path)
    _request(plc, "xRd", wRdAddr=198, wRdLen=3)
    _request(plc, "xRd", wRdAddr=199, wRdLen=1)
    _request(plc, "xWr", wWrAddr=201, wWrLen=2, wOut0=11, wOut1=22)
    _request(plc, "xWr", wWrAddr=10, wWrLen=1, wOut0=33)
    assert server.log == [(3, 198, 3), (3, 199, 1), (16, 201, 2), (16, 10, 1)]
    assert server.holding[201:203] == [11, 22] and server.holding[10] == 33
    # the second read (one register) changed the first image word only
    assert (plc["MAIN.wIn0"], plc["MAIN.wIn1"], plc["MAIN.wIn2"]) == (8, 8, 9)
    assert plc["MAIN.nErr"] == 0


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_bad_address_or_quantity_fails_the_request_with_a_status(compiler, server, st_file, tmp_path):
    plc = _build(server, st_file, tmp_path)
    _request(plc, "xRd", wRdAddr=65535, wRdLen=2)    # past Modbus address 65535: not sent
    assert plc["MAIN.wLastStatus"] == 1022
    _request(plc, "xRd", wRdAddr=0, wRdLen=4)        # more than the range's size: not sent
    assert plc["MAIN.wLastStatus"] == 1022
    _request(plc, "xRd", wRdAddr=999, wRdLen=3)      # the server's exception 02
    assert plc["MAIN.wLastStatus"] == 2
    assert server.log == [(3, 999, 3)]
    assert plc["MAIN.nErr"] == 3


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_address_key_needs_the_trigger_policy(compiler, server, st_file, tmp_path):
    with pytest.raises(PlcError, match=r"plc.conf:\d+: error: .*address: needs policy = trigger"):
        _build(server, st_file, tmp_path, channel=False)
