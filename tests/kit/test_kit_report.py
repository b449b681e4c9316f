"""The failure report's parts (kit/mipkit/report.py): the MIP blocks found in a program by
type, their diagnosis with st_lib's enum names, the readable trace."""
import json
import re

from kit_helpers import EXAMPLE


def lib():
    from mipcosim import programs as L
    return L.lib_sources()


def blocks_of(sources, tmp_path):
    from mipkit.net import build
    from mipkit.report import display_path, find_blocks
    res = build(sources, tmp_path)
    return [(display_path(p, res.programs), t) for p, t, _ in find_blocks(res.symbols, res.programs)]


BUFFER_PROGRAM = """PROGRAM Buf
VAR
  data : MIP_T_Buffer;
  bs : MIP_BufferSender;
  plain : MIP_Sender;
END_VAR
bs(aBuffer := data);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK t(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM b WITH t : Buf;
  END_RESOURCE
END_CONFIGURATION
"""


def test_blocks_are_found_by_type(tmp_path):
    """Every instance of the four blocks, outermost only (a MIP_Link's or MIP_BufferSender's own
    MIP_Sender and MIP_Receiver are its parts), whatever the integrator named them."""
    import warnings
    from mipcosim import programs as L
    warnings.simplefilter("ignore")
    assert blocks_of(lib() + [EXAMPLE / "st" / "FieldLogger.st", EXAMPLE / "st" / "Outstation.st"],
                     tmp_path / "a") == [("FIELDSTATION.SND", "MIP_Sender")]
    assert blocks_of(L.program_sources("central", False), tmp_path / "b") == \
        [(f"CENTRAL.APP.STA{i}.RCV", "MIP_Receiver") for i in range(1, 5)]
    assert blocks_of(L.program_sources("central", True), tmp_path / "c") == \
        [(f"CENTRALBIDI.APP.STA{i}.LINK", "MIP_Link") for i in range(1, 5)]
    src = tmp_path / "Buf.st"
    src.write_text(BUFFER_PROGRAM)
    assert blocks_of(lib() + [src], tmp_path / "d") == [("BUF.BS", "MIP_BufferSender"),
                                                        ("BUF.PLAIN", "MIP_Sender")]


def test_diagnosis_members_and_names_come_from_st_lib():
    from mipcosim import programs as L
    from mipkit.report import describe, enum_name, signatures
    sig = signatures()
    assert [n for n, _ in sig["MIP_Sender"][1]] == ["eState", "eWaitReason", "wWaitFor", "eErrorId"]
    assert [n for n, _ in sig["MIP_Receiver"][1]] == ["eState", "eWaitReason", "wWaitFor", "eErrorId",
                                                       "eLastErrorId"]
    assert [n for n, _ in sig["MIP_Link"][1]] == ["eSendState", "eRecvState", "eSendWaitReason",
                                                   "eRecvWaitReason", "eSendErrorId", "eRecvErrorId"]
    waits = L.enum_values("E_MIP_WaitReason")
    assert enum_name("E_MIP_WaitReason", waits["MIP_WAIT_SNAPSHOT"]) == "MIP_WAIT_SNAPSHOT"
    assert enum_name("E_MIP_WaitReason", 99) == "#99"
    diag = sig["MIP_Sender"][1]
    values = (L.enum_values("E_MIP_SenderState")["MIP_SND_WAIT_ACK"], waits["MIP_WAIT_ACK"], 7,
              L.enum_values("E_MIP_Error")["MIP_ERR_NONE"])
    assert describe(values, diag) == ("eState=MIP_SND_WAIT_ACK eWaitReason=MIP_WAIT_ACK wWaitFor=7 "
                                      "eErrorId=MIP_ERR_NONE")


def ev(t_ms, **kw):
    return json.dumps({"t": int(t_ms * 1_000_000), "seq": 0, **kw}) + "\n"


def test_trace_summary_folds_empty_polls_and_marks_the_fault():
    from mipkit.report import trace_summary
    lines = [ev(0, ev="modbus", ep="trm", st=1, fc=3, ra=2198, rq=125, exc=0)]
    lines += [ev(1 + k, ev="radio", kind="poll", dir="down", st=1, regs=0, lost=k == 3) for k in range(5)]
    lines += [ev(30, ev="modbus", ep="trm", st=1, fc=16, wa=2001, wq=9, w0=7, exc=0),
              ev(32, ev="radio", kind="answer", dir="up", st=1, regs=9, r0=7, lost=False),
              ev(1500, ev="radio", kind="poll", dir="down", st=1, regs=1, r0=7, lost=True)]
    assert trace_summary(lines, 1, t_mark=32_000_000) == [
        "             ... 6 empty polls/answers (1 lost) and reads (0.000 s .. 0.005 s)",
        "    0.030 s  Modbus at the TRM station 1: FC16 write at 2001: [0]=7 (9 registers)",
        "    0.032 s  radio station 1 -> MDP: answer, block [0]=7 (9 registers)   <- the fault",
        "    1.500 s  radio MDP -> station 1: poll, block [0]=7 (1 register): LOST",
    ]


def test_the_fault_at_an_integrators_own_central(tmp_path):
    """No peer receives: the records are those the central PLC's MIP_Receiver delivered."""
    from mipcosim import programs as L
    from mipkit import Net
    from mipkit.failure import failure_report
    conf = tmp_path / "central.conf"
    conf.write_text(L.central_config(502, 2))
    records = [[n, 100 + n, 200 + n] for n in range(1, 8)]
    with Net(tmp_path / "net", 2, radio="fast", seed=9) as net:
        cen = net.plc("central", L.program_sources("central", False), conf, at="mdp")
        peer = net.peer("outstation", at=2, records=records)
        for i, w in enumerate(L.Params(records=7, payload=3, station=0).words()):
            cen[f"%MW{i}"] = w
        assert net.run_until(lambda: peer.done, within_s=120)
        head, _, _ = failure_report(net, "record 3: got [3, 0], want [3, 1]", tmp_path / "r")
        assert re.fullmatch(r"mip-kit: fault: record 3: central CENTRAL\.APP\.STA2\.RCV delivered it by "
                            r"\d+\.\d{3} s \(sampled every 100 ms\)", head[0]), head[0]
        assert head[1].startswith("mip-kit: the blocks at the fault (")
        rcv2 = next(l for l in head[2:] if l.startswith("  central CENTRAL.APP.STA2.RCV (MIP_Receiver): "))
        assert "eWaitReason=MIP_WAIT_RECORD" in rcv2
        blocks = [l.split(" (MIP_Receiver)")[0] for l in head if l.startswith("  central ")]
        assert blocks[:4] == [f"  central CENTRAL.APP.STA{i}.RCV" for i in range(1, 5)]
        head, _, _ = failure_report(net, "not complete", tmp_path / "r2")
        assert head[0].startswith("mip-kit: fault: record 8: never delivered by central "
                                  "CENTRAL.APP.STA2.RCV (it delivered 7 records, the last at "), head[0]


def test_a_failure_that_is_not_about_records_says_none_is_missing(example):
    """Every record arrived, another expectation failed: the report does not invent a missing
    record; it is centred on the end of the deliveries."""
    from kit_helpers import mipkit_cli
    from test_kit_quick import SMALL, scenario
    text = SMALL.replace('{ at = "outstation:%MW16", equals = 0 }', '{ at = "outstation:%MW16", equals = 3 }')
    r = mipkit_cli([scenario(example, text)], example)
    lines = r.stdout.splitlines()
    assert lines[0] == "FAIL value outstation:%MW16: outstation:%MW16 = 0, want 3", r.stdout
    assert re.fullmatch(r"mip-kit: fault: no record missing: central accepted 120 records in 2 "
                        r"complete transfers, the last at \d+\.\d{3} s", lines[1]), r.stdout
