"""The durability handshake ([retain] request / saved, docs/retain.md#durability-handshake): a
program asks for a snapshot at the end of a scan and sees in the next scan that it completed;
after a kill -9 a warm start restores exactly the last completed snapshot."""
import struct
import subprocess
import time

import pytest

from plcharness import Plc, build_program
from miptest.rt import COMPILERS, one_task

EVERY = 5   # the program requests a snapshot every EVERY scans (of its retained counter)

# The pattern of docs/retain.md: remember `saved` when asking; the state of that scan is durable
# as soon as `saved` differs. `durable` is what the program could now show a peer.
PROG = one_task("""
PROGRAM MAIN
VAR RETAIN cnt : UINT; END_VAR
VAR
  req AT %QX8.0 : BOOL;
  saved AT %IW8 : WORD;
  out AT %QW100 : WORD;
  durable AT %QW101 : WORD;
END_VAR
VAR
  seen : WORD;
  waitFor : WORD;
  pending : BOOL;
  reqCnt : UINT;
END_VAR
cnt := cnt + 1;
seen := saved;
IF pending AND saved <> waitFor THEN
  durable := UINT_TO_WORD(reqCnt);
  pending := FALSE;
END_IF;
req := FALSE;
IF NOT pending AND (cnt MOD {every}) = 0 THEN
  req := TRUE;
  pending := TRUE;
  waitFor := saved;
  reqCnt := cnt;
END_IF;
out := UINT_TO_WORD(cnt);
END_PROGRAM
""")

HANDSHAKE = "[retain]\nfile = {file}\nperiod = {period}\nrequest = %QX8.0\nsaved = %IW8\n"

MODBUS = """[master]
polling_period = 10ms
[device out]
host = 127.0.0.1
port = {port}
[write status]
device = out
start = 0
size = 2
image = %QW100
policy = cycle
"""


@pytest.fixture
def prog(tmp_path, st_file):
    def make(every=EVERY):
        return build_program([st_file(PROG.replace("{every}", str(every)), name=f"sync{every}.st")],
                             tmp_path / f"sync{every}")
    return make


def snapshot_counter(path):
    """cnt from a retain file: after the 24-byte header, the first retained variable (a UINT)."""
    return struct.unpack_from("<H", path.read_bytes(), 24)[0]


def test_saved_changes_exactly_in_the_scan_after_a_request(prog, tmp_path):
    retain = tmp_path / "plc.retain"
    cfg = tmp_path / "plc.conf"
    cfg.write_text(HANDSHAKE.format(file=retain, period="0"))   # on request only
    plc = Plc(prog(), tmp_path, config=cfg)
    rows = []
    for _ in range(23):
        plc.scan()
        rows.append((plc["MAIN.cnt"], plc["MAIN.req"], plc["MAIN.seen"], plc["MAIN.durable"]))
    assert [c for c, req, _, _ in rows if req] == [5, 10, 15, 20]
    for (cnt, req, seen, _), (_, _, seen_next, durable_next) in zip(rows, rows[1:]):
        assert seen_next == seen + (1 if req else 0), rows
        if req:   # durable in the next scan: the state of the requesting scan
            assert durable_next == cnt
    assert rows[-1][2] == 4 and plc.retain_saves == 4
    assert snapshot_counter(retain) == 20     # the file holds the last requested scan's state
    plc.close()


def test_a_period_and_requests_count_in_one_word(prog, tmp_path):
    cfg = tmp_path / "plc.conf"
    cfg.write_text(HANDSHAKE.format(file=tmp_path / "plc.retain", period="100ms"))
    plc = Plc(prog(every=1000), tmp_path, config=cfg)  # no request for 1000 scans
    plc.scan(35)                 # periodic snapshots at 100, 200, 300 ms
    assert (plc["MAIN.seen"], plc.retain_saves) == (3, 3)
    plc.close()


def test_kill_9_then_warm_start_restores_the_last_completed_snapshot_not_later(prog, tmp_path, server):
    every = 20                   # 200 ms between requested snapshots, no periodic ones
    exe = prog(every).executable
    retain = tmp_path / "plc.retain"
    cfg = tmp_path / "plc.conf"
    cfg.write_text(MODBUS.format(port=server.port) + HANDSHAKE.format(file=retain, period="0"))
    restored = 0
    for i in range(3):
        p = subprocess.Popen([str(exe), "-c", str(cfg), "-m", "real"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            end = time.monotonic() + 60
            # two snapshots of this run were announced durable (seen by the peer)
            while server.holding[1] < restored + 2 * every:
                assert time.monotonic() < end and p.poll() is None, "no progress"
                time.sleep(0.01)
            time.sleep(0.03 + 0.041 * i)   # somewhere between two snapshots
            durable_seen = server.holding[1]
        finally:
            p.kill()
            p.wait()
        at_kill = snapshot_counter(retain)
        warm = subprocess.run([str(exe), "-c", str(cfg), "-m", "virtual", "-n", "1"],
                              capture_output=True, text=True, timeout=120)
        assert warm.returncode == 0, warm.stderr
        assert "warm start: 1 retained variables restored" in warm.stderr, warm.stderr
        restored = server.holding[0] - 1           # cnt after the one warm scan, minus it
        assert restored == at_kill
        assert restored % every == 0, (restored, "the state of a later scan than the last request")
        assert restored >= durable_seen, "something announced durable was lost"
        assert restored > 0


@pytest.mark.parametrize("text,message", [
    ("[retain]\nrequest = %QX8.0\n", ":1: error: [retain]: missing key 'file' (request and saved"),
    ("[retain]\nfile = r\nsaved = %IW1024\n", ":3: error: saved: '%IW1024' is outside the image"),
    ("[retain]\nfile = r\nrequest = %QW8\n", ":3: error: request: '%QW8' must be a %QX address"),
    (MODBUS.format(port=502) + "[retain]\nfile = r\nrequest = %QX8.0\nsaved = %IW8\n"
     "[read back]\ndevice = out\nstart = 0\nsize = 2\nimage = %IW7\n",
     ":20: error: image: %IW8 overlaps what line 15 uses"),
])
def test_handshake_config_errors_are_one_line_and_exit_2(prog, tmp_path, text, message):
    cfg = tmp_path / "bad.conf"
    cfg.write_text(text)
    proc = subprocess.run([str(prog().executable), "-c", str(cfg), "--check"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and f"{cfg}{message}" in proc.stderr, proc.stderr


def test_the_handshake_with_a_program_that_retains_nothing_is_refused(tmp_path, st_file):
    """saved would count snapshots holding none of the program's state."""
    from miptest.rt import COUNTER
    exe = build_program([st_file(COUNTER, name="counter.st")], tmp_path / "counter").executable
    cfg = tmp_path / "plc.conf"
    cfg.write_text(HANDSHAKE.format(file=tmp_path / "plc.retain", period="1s"))
    for mode in (["--check"], ["-m", "virtual", "-n", "3"]):
        proc = subprocess.run([str(exe), "-c", str(cfg), *mode], capture_output=True, text=True,
                              timeout=60)
        assert proc.returncode == 2
        assert proc.stderr.count("\n") == 1, proc.stderr
        assert f"{cfg}: error: [retain] request/saved: the program has no RETAIN variables" in proc.stderr
    assert not (tmp_path / "plc.retain").exists()


CLOCK_PROG = one_task("""
PROGRAM MAIN
VAR RETAIN
  tmr : TON;
  go : BOOL;
END_VAR
tmr(IN := go, PT := T#5s);
END_PROGRAM
""")


@pytest.mark.parametrize("compiler", COMPILERS)
def test_a_warm_start_starts_a_retained_timer_again(tmp_path, compiler):
    """st_lib/PROTOCOL.md W3, "the timers start again": stc keeps a standard timer's IN, PT, Q
    and ET, not its start time, and the scan clock starts at 0 on every start; so a TON 3 s
    into its 5 s when the snapshot was taken times its 5 s anew after the warm start (never
    a start time in the future that would hold it for the previous uptime). A matiec build
    keeps the same variables (matiec marks the timer's internal state retained too)."""
    from plcharness import Plc
    src = tmp_path / "clock.st"
    src.write_text(CLOCK_PROG)
    plc = Plc.build([str(src)], workdir=tmp_path, compiler=compiler)
    plc.scan(100)                                # scans at 0 .. 0.99 s
    plc["MAIN.go"] = True
    plc.scan(300)                                # the timer started at 1 s: 1 .. 3.99 s
    assert plc["MAIN.tmr.ET"] == 2_990_000_000 and not plc["MAIN.tmr.Q"]
    snap = plc.retain_save()
    warm = Plc(plc.build_result, tmp_path)       # a fresh copy of the program: a restart
    warm.retain_load(snap)
    assert warm["MAIN.tmr.ET"] == 2_990_000_000  # restored ...
    warm.scan(500)                               # ... then timed again: 0 .. 4.99 s
    assert not warm["MAIN.tmr.Q"] and warm["MAIN.tmr.ET"] == 4_990_000_000
    warm.scan(1)
    assert warm["MAIN.tmr.Q"]
