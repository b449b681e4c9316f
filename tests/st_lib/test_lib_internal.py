"""The internal blocks MIP_Internal_Layout and MIP_Internal_ReadDecoder on their own: the tables the sender, the
receiver and the link rely on (st_lib/PROTOCOL.md section 1, note 2.1 and 2.2)."""

import pytest
from mipprograms.common import config
from plcharness import Plc

from stlib_sim import LIB_PATHS, compiler

PROGRAM = """
PROGRAM MAIN
VAR
  lay : MIP_Internal_Layout;
  dec : MIP_Internal_ReadDecoder;
  xBidi, xDown, xEnable, xReset, xReadValid : BOOL;
  wStatus, wCount, wNumber : WORD;
  uStream : UINT;
END_VAR
lay(xBidirectional := xBidi, xDownstream := xDown);
dec(xEnable := xEnable, xReset := xReset, xReadValid := xReadValid, wStatus := wStatus,
    wCount := wCount, wNumber := wNumber, uStream := uStream);
END_PROGRAM
""" + config("MAIN", "inst0")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    wd = tmp_path_factory.mktemp("stlib_internal")
    prog = wd / "prog.st"
    prog.write_text(PROGRAM)
    return Plc.build(LIB_PATHS + [str(prog)], workdir=wd, compiler=compiler()).build_result, wd


@pytest.fixture
def plc(built):
    result, wd = built
    p = Plc(result, wd)
    p["MAIN.xEnable"] = True
    return p


@pytest.mark.parametrize("bidi,down,header,stream,other", [
    (False, False, 1, 0, 0),   # note 2.1: one counter at 0, payload from 1, either direction
    (False, True, 1, 0, 0),
    (True, False, 2, 0, 1),    # note 2.2: outstation stream at 0 ...
    (True, True, 2, 1, 0),     # ... central stream at 1, payload from 2
])
def test_layout_table(plc, bidi, down, header, stream, other):
    plc["MAIN.xBidi"], plc["MAIN.xDown"] = bidi, down
    plc.scan()
    assert (plc["MAIN.lay.uHeader"], plc["MAIN.lay.uStream"], plc["MAIN.lay.uOther"]) == \
        (header, stream, other)


def read(plc, status, count, number, valid=True, stream=0):
    plc["MAIN.wStatus"], plc["MAIN.wCount"], plc["MAIN.wNumber"] = status, count, number
    plc["MAIN.xReadValid"], plc["MAIN.uStream"] = valid, stream
    plc.scan()
    return {k: plc[f"MAIN.dec.{k}"] for k in ("xValid", "wNum", "uCount", "xNewData",
                                                "xUnconfirmed", "xNewTelegram", "xHaveNum")}


def test_first_block_is_a_new_telegram_then_only_a_rising_bit_or_another_number(plc):
    r = read(plc, 0x0000, 3, 7)
    assert r["xValid"] and r["xNewTelegram"] and r["wNum"] == 7 and r["xHaveNum"]
    assert not read(plc, 0x0000, 3, 7)["xNewTelegram"]      # the same block read again
    assert read(plc, 0x0001, 3, 7)["xNewTelegram"]          # bit 0 rose: the same number again
    assert not read(plc, 0x0001, 3, 7)["xNewTelegram"]      # bit still set: not new
    r = read(plc, 0x0001, 3, 8)                             # another number, bit missed
    assert r["xNewTelegram"] and r["wNum"] == 8


def test_a_scan_without_a_read_neither_takes_nor_forgets(plc):
    read(plc, 0x0001, 3, 5)
    r = read(plc, 0x0000, 0, 0, valid=False)
    assert not r["xValid"] and not r["xNewTelegram"] and r["wNum"] == 5
    # a call without a read counts as bit 0 clear: with a read every few scans (the runtime's
    # trigger policy) every read with the bit set is a new telegram ...
    assert read(plc, 0x0001, 3, 5)["xNewTelegram"]
    # ... with a read every scan (cyclic I/O) only a rise is
    assert not read(plc, 0x0001, 3, 5)["xNewTelegram"]


def test_a_block_without_the_streams_counter_is_not_taken(plc):
    read(plc, 0x0001, 3, 5)
    r = read(plc, 0x0001, 1, 9, stream=1)                   # count 1: no register at index 1
    assert not r["xValid"] and not r["xNewTelegram"] and r["wNum"] == 5 and r["uCount"] == 1
    r = read(plc, 0x0001, 2, 9, stream=1)
    assert r["xValid"] and r["xNewTelegram"] and r["wNum"] == 9


def test_disabled_takes_no_number_but_follows_the_bits(plc):
    plc["MAIN.xEnable"] = False
    r = read(plc, 0x0011, 3, 4)
    assert not r["xValid"] and not r["xHaveNum"] and r["xNewData"] and r["xUnconfirmed"]
    plc["MAIN.xEnable"] = True
    # bit 0 was already set at the last read: the first number still counts as new
    assert read(plc, 0x0001, 3, 4)["xNewTelegram"]


def test_reset_forgets_the_number(plc):
    read(plc, 0x0000, 3, 4)
    assert not read(plc, 0x0000, 3, 4)["xNewTelegram"]
    plc["MAIN.xReset"] = True
    r = read(plc, 0x0000, 3, 4)
    plc["MAIN.xReset"] = False
    assert r["xNewTelegram"] and r["xHaveNum"]
    assert not read(plc, 0x0000, 3, 4)["xNewTelegram"]
