"""MIP_SoeServer in the soft PLC, polled over Modbus TCP by the SCADA stand-in (issue 35, the pull
way): every entry once, in order, time stamps unchanged; a lost acknowledgement answer, a wrong
acknowledgement, a silent SCADA and a warm restart between serve and acknowledgement lose and
repeat nothing. The PLC runs in virtual time; the SCADA in a thread, served in each scan's I/O
phase."""
import sys
import threading
import time
from pathlib import Path

import pytest

from plcharness import Plc, PlcError, build_program
from plcharness.config import Config

from mippeer.scada import Client, ScadaError, SoeMaster
from mipcosim.programs import LIB_FILES, ST_LIB, enum_values
from miptest.rt import one_task

REPO = Path(__file__).resolve().parents[2]

BASE = 600                  # the registers at %QW600..625 = holding 600..625, as the relay's 40601..
TS0 = 1767225600000         # time stamp of entry 0 (ms since 1970)
STATES = enum_values("E_MIP_SoeSrvState", ST_LIB / "chain" / "MIP_TypesSoeServer.st")
ERRORS = enum_values("E_MIP_ChainError", ST_LIB / "chain" / "MIP_TypesSoe.st")
WAIT = enum_values("E_MIP_ChainWaitReason", ST_LIB / "chain" / "MIP_TypesSoe.st")

REGS = "\n".join(f"  r{i} AT %QW{BASE + i} : WORD;" for i in range(26))
COPY = "\n".join(f"r{i} := srv.aRegs[{i}];" for i in range(26))
PROG = one_task(f"""
PROGRAM MAIN
VAR RETAIN
  srv : MIP_SoeServer;
  uNext : UINT := 1;        (* the next entry to put *)
END_VAR
VAR
{REGS}
  wWrites AT %IW9 : WORD;   (* [slave] watch_count: the SCADA's writes to SOE_Control *)
  wSaved AT %IW8 : WORD;    (* [retain] saved *)
  xReq AT %QX8.0 : BOOL;    (* [retain] request *)
  wTotal AT %MW0 : WORD;    (* entries to put *)
  wRetained AT %MW1 : WORD; (* 1: xRetained *)
  wSilent AT %MW2 : WORD;   (* 1: tAckTimeout 2 s, else never *)
END_VAR
VAR
  e : MIP_T_SoeSrvEntry;
  tAck : TIME;
  uTs : UINT;
END_VAR
e[0] := WORD#16#0101;
e[1] := UINT_TO_WORD(uNext);
e[2] := WORD#16#0101;
e[3] := UINT_TO_WORD(uNext MOD 2);
uTs := 43008 + uNext;       (* TS0 + uNext: 411, 30426, 43008 + n below *)
e[4] := WORD#0;
e[5] := WORD#411;
e[6] := WORD#30426;
e[7] := UINT_TO_WORD(uTs);
IF wSilent <> 0 THEN tAck := T#2s; ELSE tAck := T#0s; END_IF;
srv(xEnable := TRUE, xRetained := wRetained <> 0, tAckTimeout := tAck,
    xPut := uNext <= WORD_TO_UINT(wTotal), aEntry := e,
    wCtrlWritten := r1, wCtrlWrites := wWrites, wSnapshots := wSaved);
IF srv.xTaken THEN uNext := uNext + 1; END_IF;
xReq := srv.xSnapshotReq;
{COPY}
END_PROGRAM
""")
def config(retain_file) -> str:
    """The slave on a free port counting the SCADA's writes to SOE_Control (%QW601) in %IW9;
    snapshots on request only (the program's handshake %QX8.0 / %IW8)."""
    cfg = Config()
    cfg.add("slave", port=0, watch="%QW601", watch_count="%IW9")
    cfg.add("retain", file=retain_file, period=0, request="%QX8.0", saved="%IW8")
    return cfg.text()


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    d = tmp_path_factory.mktemp("soe_server")
    src = d / "soe_server.st"
    src.write_text(PROG)
    return build_program([str(REPO / "st_lib" / f) for f in LIB_FILES] + [str(src)], d / "build")


def start(build, tmp_path, total, retained=False, silent=False, snap=None):
    cfg = tmp_path / "plc.conf"
    cfg.write_text(config(tmp_path / "plc.retain"))
    plc = Plc(build, tmp_path, config=cfg)
    plc.retain_in_memory(0)              # snapshots on the block's request only
    if snap is not None:
        plc.retain_load(snap)
    plc["%MW0"], plc["%MW1"], plc["%MW2"] = total, int(retained), int(silent)
    return plc


def expected(n):
    return [(k, TS0 + k) for k in range(1, n + 1)]


def taken(rows):
    return [(r["address"], r["ts_ms"]) for r in rows]


def run(plc, master, until, max_scans=20000):
    """Scans while the SCADA polls in a thread, until until() or max_scans; the SCADA's request
    in flight when it stops is served by a few more scans."""
    stop = threading.Event()

    def scada():
        while not stop.is_set():
            try:
                master.poll(time.monotonic())
            except ScadaError:
                pass

    t = threading.Thread(target=scada, daemon=True)
    t.start()
    try:
        for _ in range(max_scans):
            plc.scan()
            time.sleep(0.0001)
            if until():
                break
    finally:
        stop.set()
        while t.is_alive():
            plc.scan()
            t.join(0.001)


def scada(plc, rows, reack=0.05):
    return SoeMaster(Client("127.0.0.1", plc.slave_port, timeout=5), BASE, rows.extend, reack)


def test_every_entry_once_in_order_with_its_time_stamp(build, tmp_path):
    plc = start(build, tmp_path, total=20)
    rows = []
    m = scada(plc, rows)
    run(plc, m, lambda: plc["MAIN.srv.udiAcked"] == 20)
    assert taken(rows) == expected(20)
    assert [r["value"] for r in rows] == [k % 2 for k in range(1, 21)]
    assert plc["MAIN.srv.udiPut"] == 20 and plc["MAIN.srv.udiBadAcks"] == 0
    assert plc["MAIN.srv.eState"] == STATES["MIP_SRV_IDLE"]
    assert plc["MAIN.srv.eWaitReason"] == WAIT["MIP_CHAIN_WAIT_PUT"] and plc["MAIN.srv.xValid"]
    assert plc["%QW600"] == 0 and plc["%QW601"] >> 8 == 0      # count 0, nothing offered
    plc.close()


def test_a_lost_acknowledgement_answer_is_repeated_not_duplicated(build, tmp_path):
    plc = start(build, tmp_path, total=12)
    rows = []
    m = scada(plc, rows)
    m.lose_answers = {1, 3}          # the first and third acknowledgements' answers are lost
    run(plc, m, lambda: plc["MAIN.srv.udiAcked"] == 12)
    assert taken(rows) == expected(12)
    assert plc["MAIN.srv.udiAcked"] == 12 and plc["MAIN.srv.uQueued"] == 0
    plc.close()


def write_ctrl(plc, value):
    """One FC6 write of SOE_Control through the PLC's slave, served by the scans."""
    c = Client("127.0.0.1", plc.slave_port, timeout=5)
    res = []
    t = threading.Thread(target=lambda: res.append(c.write_register(BASE + 1, value)), daemon=True)
    t.start()
    while t.is_alive():
        plc.scan()
        t.join(0.001)
    c.close()
    plc.scan()
    assert res == [None]


def test_a_wrong_acknowledgement_is_refused_and_changes_nothing(build, tmp_path):
    plc = start(build, tmp_path, total=4)
    plc.scan(10)
    regs = [plc[f"%QW{BASE + i}"] for i in range(26)]
    seq, n = regs[1] & 0xFF, regs[1] >> 8
    assert (regs[0], n) == (4, 3) and plc["MAIN.srv.eState"] == STATES["MIP_SRV_OFFERED"]
    assert plc["MAIN.srv.eWaitReason"] == WAIT["MIP_CHAIN_WAIT_SCADA"]
    for bad in (seq + 1 + (3 << 8),          # another sequence number
                seq + (4 << 8),              # more entries than offered
                seq + (3 << 8) + 0x8000,     # reset list: the server never deletes untaken entries
                0x8000):                     # reset list without data
        write_ctrl(plc, bad)
        assert [plc[f"%QW{BASE + i}"] for i in range(26)] == regs, hex(bad)
    assert plc["MAIN.srv.udiBadAcks"] == 4 and plc["MAIN.srv.wLastBadAck"] == 0x8000
    assert plc["MAIN.srv.udiAcked"] == 0
    write_ctrl(plc, seq + (2 << 8))          # 2 of the 3 evaluated: they go, the third comes again
    assert plc["MAIN.srv.udiAcked"] == 2 and plc["%QW600"] == 2
    assert plc["%QW601"] == ((seq + 1) | 2 << 8)                  # entries 3 and 4, a new number
    assert plc[f"%QW{BASE + 3}"] == 3 and plc[f"%QW{BASE + 11}"] == 4
    write_ctrl(plc, seq + 1 + (3 << 8))      # more than the 2 offered now
    assert plc["MAIN.srv.udiBadAcks"] == 5 and plc["MAIN.srv.uQueued"] == 2
    write_ctrl(plc, seq + 1 + (2 << 8))
    assert plc["MAIN.srv.udiAcked"] == 4 and plc["%QW600"] == 0 and plc["%QW601"] == seq + 1
    write_ctrl(plc, seq + 1 + (2 << 8))      # the same again (its answer lost): nothing offered
    assert plc["MAIN.srv.udiBadAcks"] == 6 and plc["MAIN.srv.udiAcked"] == 4
    plc.close()


def test_a_silent_scada_is_named_and_loses_nothing(build, tmp_path):
    plc = start(build, tmp_path, total=7, silent=True)
    plc.scan(150)
    assert not plc["MAIN.srv.xError"]
    plc.scan(100)                            # 2 s after the offer: the SCADA is silent
    assert plc["MAIN.srv.xError"]
    assert plc["MAIN.srv.eErrorId"] == ERRORS["MIP_SRV_ERR_SCADA_SILENT"]
    assert plc["MAIN.srv.eState"] == STATES["MIP_SRV_SCADA_SILENT"] and not plc["MAIN.srv.xValid"]
    assert plc["MAIN.srv.eWaitReason"] == WAIT["MIP_CHAIN_WAIT_SCADA"] and not plc["MAIN.srv.xBusy"]
    assert plc["MAIN.srv.uQueued"] == 7
    rows = []
    run(plc, scada(plc, rows), lambda: plc["MAIN.srv.udiAcked"] == 7)
    assert taken(rows) == expected(7)
    assert not plc["MAIN.srv.xError"]
    plc.close()


def test_a_warm_restart_between_serve_and_acknowledgement_loses_and_repeats_nothing(build, tmp_path):
    """The snapshot holds an offer the SCADA then took and acknowledged; the PLC dies before a
    snapshot holds the acknowledgement: after the warm restart it offers the same entries under
    the same sequence number, the SCADA knows them and acknowledges again."""
    plc = start(build, tmp_path, total=9, retained=True)
    plc.scan(3)                              # entries 1..3 put, the offer formed ...
    assert plc["MAIN.srv.uOffered"] == 0 and plc["MAIN.srv.xSnapshotReq"]
    assert plc["MAIN.srv.eState"] == STATES["MIP_SRV_WAIT_SNAPSHOT"]
    assert plc["MAIN.srv.eWaitReason"] == WAIT["MIP_CHAIN_WAIT_SNAPSHOT"]
    plc.scan()                               # ... and shown once a snapshot holds it
    assert plc["MAIN.srv.uOffered"] == 3
    snap = plc.retain_last()
    assert snap is not None
    rows = []
    m = scada(plc, rows)
    run(plc, m, lambda: plc["MAIN.srv.udiAcked"] >= 3)
    assert taken(rows)[:3] == expected(3)
    # kill -9: the snapshot taken with the offer is the last one the new start finds
    plc.close()
    (tmp_path / "w").mkdir()
    plc = start(build, tmp_path / "w", total=9, retained=True, snap=snap)
    assert plc["MAIN.srv.udiAcked"] == 0 and plc["MAIN.srv.udiPut"] >= 3
    m.c.close()
    m.c = Client("127.0.0.1", plc.slave_port, timeout=5)
    run(plc, m, lambda: plc["MAIN.srv.udiAcked"] == 9)
    assert taken(rows) == expected(9)        # entries 1..3 not taken twice
    assert m.reacks >= 1
    plc.close()


def test_watch_goes_with_watch_count_and_must_be_a_holding_register(build, tmp_path):
    cfg = tmp_path / "bad.conf"
    for text, msg in (("[slave]\nport = 0\nwatch = %QW601\n",
                       "watch and watch_count go together"),
                      ("[slave]\nport = 0\nwatch = %IW601\nwatch_count = %IW9\n",
                       "watch: '%IW601' must be a %QW or %MW address (a holding register)")):
        cfg.write_text(text)
        with pytest.raises(PlcError) as e:
            Plc(build, tmp_path, config=cfg)
        assert msg in str(e.value) and "\n" not in str(e.value)


def test_in_real_time_the_scada_command_takes_every_entry_once(build, tmp_path):
    """The executable in real time (slave thread, scans every 10 ms) and `mip-peer scada` as a
    separate process: the acknowledgement lands between two scans, a read before the next scan
    still shows the offer the SCADA took, and it is not taken twice."""
    import re
    import signal
    import subprocess
    import json
    cfg = tmp_path / "rt.conf"
    cfg.write_text(config(tmp_path / "rt.retain"))
    plc = subprocess.Popen([str(build.executable), "-c", str(cfg), "-m", "real"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        m = re.search(r"listening on 127\.0\.0\.1:(\d+)", plc.stderr.readline())
        assert m
        port = int(m.group(1))
        c = Client("127.0.0.1", port)
        c.write_register(1024, 30)                        # %MW0: 30 entries
        c.close()
        out = tmp_path / "e.jsonl"
        p = subprocess.run([sys.executable, "-m", "mippeer.cli", "scada", "--port", str(port),
                            "--out", str(out), "--entries", "30", "--interval", "0.005"],
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 0, p.stderr
        assert taken([json.loads(x) for x in out.read_text().splitlines()]) == expected(30)
        assert re.fullmatch(r"mip-peer scada: entries=30 acks=1\d reacks=0 refused=0", p.stdout.strip())
    finally:
        plc.send_signal(signal.SIGTERM)
        plc.wait(timeout=10)
        plc.stderr.close()


def test_the_hand_over_round_in_virtual_time(build, tmp_path):
    """Lockstep (one thread, virtual time): an entry every 230 ms, the SCADA polling every
    100 ms; each entry's time from its put to the SCADA's acknowledgement is at most one polling
    interval plus three scans (docs/chain.md, the trade-off, quotes the figures it prints)."""
    import select
    plc = start(build, tmp_path, total=0)
    put_at, ack_at = {}, {}

    def tick():
        plc.scan()
        for k in range(len(put_at) + 1, plc["MAIN.srv.udiPut"] + 1):
            put_at[k] = plc.time_ns
        for k in range(len(ack_at) + 1, plc["MAIN.srv.udiAcked"] + 1):
            ack_at[k] = plc.time_ns

    def serve():                           # scans until the answer is there
        for _ in range(10):
            tick()
            if select.select([client.sock], [], [], 0.05)[0]:
                return
        raise AssertionError("no answer within 10 scans")

    client = Client("127.0.0.1", plc.slave_port, timeout=5, after_send=serve)
    rows = []
    m = SoeMaster(client, BASE, rows.extend, reack=1.0)
    for n in range(1, 381):                # 3.8 s of virtual time
        if n % 23 == 0 and n <= 345:
            plc["%MW0"] = n // 23          # one more entry, every 230 ms: all phases of the poll
        if n % 10 == 0:
            m.poll(plc.time_ns / 1e9)
        tick()
    client.close()
    assert taken(rows) == expected(15)
    lat = sorted((ack_at[k] - put_at[k]) / 1e6 for k in range(1, 16))
    print("put -> acknowledged, ms:", lat)
    # the scan after the put (the offer forms without xPut), up to a polling interval, one scan
    # for the read and one for the write
    assert 3 * 10 <= lat[0] and lat[-1] <= 100 + 3 * 10, lat
    assert m.reacks == 0 and plc["MAIN.srv.udiBadAcks"] == 0
    plc.close()


def test_a_full_queue_refuses_entries_and_takes_them_once_there_is_room(build, tmp_path):
    plc = start(build, tmp_path, total=130)
    plc.scan(140)                            # no SCADA: 128 fit
    assert plc["MAIN.srv.xFull"] and plc["MAIN.srv.udiPut"] == 128
    assert plc["%QW600"] == 128 and plc["MAIN.uNext"] == 129      # the caller keeps entry 129
    rows = []
    run(plc, scada(plc, rows), lambda: plc["MAIN.srv.udiAcked"] == 130)
    assert taken(rows) == expected(130)
    assert not plc["MAIN.srv.xFull"]
    plc.close()
