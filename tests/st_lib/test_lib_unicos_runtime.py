"""MIP_UnicosEvents behind plcrt's own Modbus master (a trigger write range, its done / error /
status bits), whose device is the WinCC OA stand-in through cosim/mipcosim/pydevice.py: the
stand-in as a device of a PLC in virtual time, as the chain's co-simulation will use it."""
import pytest

from mipcosim.pydevice import PyDevice
from mippeer.unicos import UnicosConfig, UnicosDriver
from plcharness import Plc
from plcharness.config import Config
from stlib_sim import compiler, lib_sources, lib_type
from unicos_bench import UERR, entry

MARKER = 0xFF80          # 16#FFFF + 123 registers would run past address 65535: plcrt refuses it
T0 = 1767225600000


def program():
    decl = ["  uni : MIP_UnicosEvents;", f"  rec : {lib_type('MIP_T_Payload')};",
            "  " + ", ".join(f"rec{i}" for i in range(24)) + " : WORD;",
            "  uLen : UINT;", "  xValid : BOOL;", f"  rep : {lib_type('MIP_T_UnicosReply')};",
            "END_VAR", "VAR",
            "  wrTrig AT %QX1.0 : BOOL;", "  wrDone AT %IX1.0 : BOOL;", "  wrErr AT %IX1.1 : BOOL;",
            "  wrStatus AT %IW10 : WORD;", "  wrLen AT %QW1 : WORD;"]
    decl += [f"  w{i} AT %QW{100 + i} : WORD;" for i in range(123)]
    body = [f"rec[{i}] := rec{i};" for i in range(24)]
    body += ["rep.xWriteDone := wrDone;", "rep.xWriteError := wrErr;", "rep.wWriteStatus := wrStatus;"]
    body += ["uni(xEnable := TRUE, aRecord := rec, uRecordLen := uLen, xRecordValid := xValid,",
             f"    wMarker := WORD#{MARKER}, tRetry := T#100ms, uMaxRetries := 1,",
             "    stReplyA := rep);",
             "wrTrig := uni.stRequestA.xWriteReq;",
             "wrLen := UINT_TO_WORD(uni.stRequestA.uWriteLen);"]
    body += [f"w{i} := uni.stRequestA.aWrite[{i}];" for i in range(123)]
    return ("PROGRAM MAIN\nVAR\n" + "\n".join(decl) + "\nEND_VAR\n" + "\n".join(body)
            + "\nEND_PROGRAM\n\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            "    TASK tMain(INTERVAL := T#10ms, PRIORITY := 0);\n"
            "    PROGRAM inst0 WITH tMain : MAIN;\n  END_RESOURCE\nEND_CONFIGURATION\n")


CONFIG = Config()
CONFIG.add("master", timeout="50ms")
CONFIG.add("device", "unicos", host="127.0.0.1", port=502)
CONFIG.add("write", "unicos_events", device="unicos", start=MARKER, size=123, image="%QW100",
           policy="trigger", trigger="%QX1.0", done="%IX1.0", error="%IX1.1", status="%IW10",
           length="%QW1")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("unicos_runtime")
    (d / "prog.st").write_text(program())
    CONFIG.write(d / "plcrt.conf")
    plc = Plc.build(lib_sources(d) + [str(d / "prog.st")], workdir=d, compiler=compiler(),
                    config=d / "plcrt.conf")
    return plc.build_result, d


def test_events_through_plcrts_master_to_the_stand_in(built):
    result, d = built
    plc = Plc(result, d, config=d / "plcrt.conf")
    driver = UnicosDriver("A", UnicosConfig(marker=MARKER))
    dev = PyDevice(plc, "unicos", driver.handle)
    records = [[entry(0x0101, 10 * r + k, 0x0101, k, T0 + 1000 * r + k * 10) for k in range(3)]
               for r in range(4)]
    driver.fail_next(2, code=6)                       # busy twice: retried, named, then taken
    errors_seen = set()
    for rec in records:
        words = sum(rec, [])
        for i, w in enumerate(words):
            plc[f"MAIN.rec{i}"] = w
        plc["MAIN.uLen"] = len(words)
        plc["MAIN.xValid"] = True
        for _ in range(200):
            plc.scan()
            dev.check()
            errors_seen.add(plc["MAIN.uni.eErrorId"])
            if plc["MAIN.uni.xRecordProcessed"]:
                break
        assert plc["MAIN.uni.xRecordProcessed"], f"record {rec} not handed over"
        plc["MAIN.xValid"] = False
        plc.scan(2)
    got = [(e["offset"], e["value"], e["ts_10ms"]) for e in driver.events]
    want = [(10 * r + k, 0x0101 << 16 | k, (T0 + 1000 * r + k * 10) // 10)
            for r in range(4) for k in range(3)]
    assert got == want and driver.duplicates == 0
    assert UERR["MIP_UNI_ERR_EXCEPTION"] in errors_seen and plc["MAIN.uni.wException"] == 6
    assert dev.requests == 4 + 2 and plc["MAIN.uni.udiRecords"] == 4


def test_no_answer_from_the_stand_in_is_plcrts_timeout(built):
    result, d = built
    plc = Plc(result, d, config=d / "plcrt.conf")
    driver = UnicosDriver("A", UnicosConfig(marker=MARKER))
    driver.mute = True
    dev = PyDevice(plc, "unicos", driver.handle)
    words = entry(0x0101, 1, 0x0101, 1, T0)
    for i, w in enumerate(words):
        plc[f"MAIN.rec{i}"] = w
    plc["MAIN.uLen"] = 8
    plc["MAIN.xValid"] = True
    plc.scan(60)
    assert plc["MAIN.uni.eErrorId"] == UERR["MIP_UNI_ERR_NO_ANSWER"]
    assert plc["MAIN.uni.wException"] == 1110 and not plc["MAIN.uni.xRecordProcessed"]
    assert dev.unanswered >= 2 and driver.events == []
    driver.mute = False
    plc.scan(40)
    assert plc["MAIN.uni.xRecordProcessed"] and len(driver.events) == 1
