"""RETAIN in the thin executable: warm / cold starts, atomic snapshots, kill -9, bad files."""
import signal
import subprocess
import time

import pytest

from plcharness import build_program
from plcharness.config import read_file
from miptest.rt import ModbusServer, compiler_param, one_task, tcp_device

PROG = one_task("""
FUNCTION_BLOCK ACC
VAR_INPUT inc : UINT; END_VAR
VAR_OUTPUT total : UINT; END_VAR
VAR n : UINT; END_VAR
n := n + inc; total := n;
END_FUNCTION_BLOCK
PROGRAM MAIN
VAR RETAIN cnt : UINT; kept : ACC; {extra} END_VAR
VAR lost : ACC; END_VAR
VAR out AT %QW100 : WORD; out2 AT %QW101 : WORD; out3 AT %QW102 : WORD; END_VAR
cnt := cnt + 1;
kept(inc := 1);
lost(inc := 1);
out := UINT_TO_WORD(cnt); out2 := UINT_TO_WORD(kept.total); out3 := UINT_TO_WORD(lost.total);
END_PROGRAM
""")

def config(port) -> str:
    """out, out2, out3 (%QW100..102) written to holding registers 0..2 every cycle."""
    cfg = tcp_device(port)
    cfg.add("write", "count", device="out", start=0, size=3, image="%QW100", policy="cycle")
    return cfg.text()


@pytest.fixture
def server():
    srv = ModbusServer()
    yield srv
    srv.close()


@pytest.fixture
def plc(tmp_path, st_file, conf_file, server):
    cfg = conf_file(config(server.port))

    def make(extra="", compiler="stc", name="out"):
        res = build_program([st_file(PROG.replace("{extra}", extra), name=f"{name}.st")],
                            tmp_path / name, compiler=compiler)
        return res.executable
    make.cfg = cfg
    make.retain = tmp_path / "plc.retain"
    return make


def run(exe, cfg, *args):
    return subprocess.run([str(exe), "-c", str(cfg), *args], capture_output=True, text=True,
                          timeout=120)


def virtual(plc, exe, scans, *args):
    return run(exe, plc.cfg, "-m", "virtual", "-n", str(scans), "--retain", str(plc.retain), *args)


def cold_then_warm(plc, exe, server):
    """20 scans from no retain file (a cold start), then 5 from its snapshot: the second run."""
    first = virtual(plc, exe, 20)
    assert first.returncode == 0, first.stderr
    assert "cold start: no retain file" in first.stderr
    assert server.holding[0:3] == [20, 20, 20]
    second = virtual(plc, exe, 5)
    assert second.returncode == 0, second.stderr
    return second


def test_warm_start_restores_retained_variables_and_whole_retained_fb_instances(plc, server):
    exe = plc()
    second = cold_then_warm(plc, exe, server)
    assert "warm start: 4 retained variables restored" in second.stderr
    # cnt and the instance in the RETAIN section (its own non-RETAIN n included) go on;
    # the instance in a plain VAR section starts again
    assert server.holding[0:3] == [25, 25, 5]


def test_cold_start_ignores_the_file_and_overwrites_it(plc, server):
    exe = plc()
    assert virtual(plc, exe, 20).returncode == 0
    cold = virtual(plc, exe, 5, "--cold")
    assert cold.returncode == 0 and "cold start (--cold)" in cold.stderr
    assert server.holding[0:3] == [5, 5, 5]
    assert virtual(plc, exe, 1, "--warm").returncode == 0
    assert server.holding[0:3] == [6, 6, 1]


@pytest.mark.parametrize("damage", ["truncated", "flipped", "foreign", "empty"])
def test_a_bad_retain_file_is_one_line_and_a_cold_start(plc, server, damage):
    exe = plc()
    assert virtual(plc, exe, 20).returncode == 0
    data = plc.retain.read_bytes()
    bad = {"truncated": data[:-3], "flipped": data[:30] + bytes([data[30] ^ 1]) + data[31:],
           "foreign": b"x" * len(data), "empty": b""}[damage]
    plc.retain.write_bytes(bad)
    proc = virtual(plc, exe, 5)
    assert proc.returncode == 0, proc.stderr
    lines = [l for l in proc.stderr.splitlines() if "cold start" in l]
    assert len(lines) == 1 and str(plc.retain) in lines[0], proc.stderr
    assert server.holding[0:3] == [5, 5, 5]


def test_a_changed_set_of_retained_variables_is_a_cold_start(plc, server):
    assert virtual(plc, plc(), 20).returncode == 0
    proc = virtual(plc, plc("more : DINT;", name="changed"), 5)
    assert proc.returncode == 0, proc.stderr
    assert "cold start" in proc.stderr and "program changed" in proc.stderr
    assert server.holding[0:3] == [5, 5, 5]


def _wait(cond, what, limit=60.0):
    end = time.monotonic() + limit
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def _stamp(path):
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return (st.st_ino, st.st_mtime_ns)   # a rename brings a new inode


def test_kill_9_between_saves_restores_the_last_complete_snapshot(plc, server):
    exe = plc()
    seen = 0
    for _ in range(6):
        before = _stamp(plc.retain)
        p = subprocess.Popen([str(exe), "-c", str(plc.cfg), "-m", "real", "--retain",
                              str(plc.retain), "--retain-period", "20"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            # at least one new snapshot, then a kill at an arbitrary point of the save cycle
            _wait(lambda: _stamp(plc.retain) not in (None, before),
                  "a retain snapshot")
            time.sleep(0.013)
        finally:
            p.kill()
            p.wait()
        check = virtual(plc, exe, 1)
        assert check.returncode == 0, check.stderr
        assert "warm start: 4 retained variables restored" in check.stderr, check.stderr
        cnt = server.holding[0]
        # the counters of the snapshot agree with each other (one consistent scan), and
        # never go back behind a snapshot that was complete before
        assert server.holding[1] == cnt and cnt > seen
        seen = cnt


def test_sigterm_saves_on_a_clean_stop(plc, server):
    exe = plc()
    p = subprocess.Popen([str(exe), "-c", str(plc.cfg), "-m", "real", "--retain",
                          str(plc.retain), "--retain-period", "0"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        _wait(lambda: server.holding[0] >= 5, "5 scans")
    finally:
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    assert p.returncode == 0, err
    stopped_at = server.holding[0]
    proc = virtual(plc, exe, 1)
    assert "warm start" in proc.stderr, proc.stderr
    assert server.holding[0] >= stopped_at + 1


@pytest.mark.parametrize("compiler", [compiler_param("matiec")])
def test_matiec_programs_keep_their_retained_variables_on_a_warm_start(plc, server, compiler):
    exe = plc("hist : ARRAY[0..3] OF UINT;", compiler=compiler, name="m")
    second = cold_then_warm(plc, exe, server)
    # the same as an stc build keeps (cnt, kept's inc, total and n) and the array, which
    # matiec cannot mark retained
    assert "warm start: 5 retained variables restored" in second.stderr, second.stderr
    assert server.holding[0:3] == [25, 25, 5]


def test_an_unwritable_retain_path_is_reported_without_flooding_or_crashing(plc, server, tmp_path):
    exe = plc()
    where = tmp_path / "a-directory"
    where.mkdir()
    proc = run(exe, plc.cfg, "-m", "virtual", "-n", "500", "--retain", str(where),
               "--retain-period", "10")
    # cold start (a directory is no snapshot), 500 failed periodic saves, the failed stop save
    assert proc.returncode == 1, proc.stderr
    assert "cold start" in proc.stderr and "not a regular file" in proc.stderr
    failures = [l for l in proc.stderr.splitlines() if "failed saves" in l]
    assert 1 <= len(failures) <= 5, proc.stderr
    assert server.holding[0] == 500


def test_the_config_can_name_the_retain_file_and_period(plc, server, tmp_path):
    exe = plc()
    cfg = tmp_path / "with-retain.conf"
    conf = read_file(plc.cfg)
    conf.add("retain", file=plc.retain, period="50ms")
    conf.write(cfg)
    first = run(exe, cfg, "-m", "virtual", "-n", "20")
    assert first.returncode == 0, first.stderr
    assert "cold start: no retain file" in first.stderr
    second = run(exe, cfg, "-m", "virtual", "-n", "5")
    assert "warm start" in second.stderr, second.stderr
    assert server.holding[0:3] == [25, 25, 5]
    # the command line wins over the config
    other = tmp_path / "other.retain"
    third = run(exe, cfg, "-m", "virtual", "-n", "5", "--retain", str(other))
    assert "cold start: no retain file" in third.stderr and other.exists()


@pytest.mark.parametrize("text,message", [
    ("[retain]\nperiod = 1s\n", "[retain]: missing key 'file'"),
    ("[retain]\nfile = x\nsize = 3\n", "unknown key 'size' in [retain]"),
    ("[retain]\nfile = x\nperiod = soon\n", "is not a duration"),
    ("[retain]\nfile = x\n[retain]\nfile = y\n", "[retain] given twice"),
])
def test_retain_config_errors_are_one_line(plc, tmp_path, text, message):
    cfg = tmp_path / "bad.conf"
    cfg.write_text(text)
    proc = run(plc(), cfg, "--check")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and message in proc.stderr, proc.stderr
    assert f"{cfg}:" in proc.stderr


def test_the_harness_restarts_a_program_warm_from_a_snapshot_in_memory(st_file, tmp_path):
    from plcharness import Plc, PlcError
    res = build_program([st_file(PROG.replace("{extra}", ""), name="mem.st")], tmp_path / "mem")
    for d in ("w1", "w2"):
        (tmp_path / d).mkdir()
    plc = Plc(res, tmp_path / "w1")
    assert plc.retain_count() == 4
    plc.scan(7)
    snap = plc.retain_save()
    plc.close()
    warm = Plc(res, tmp_path / "w2")        # config_init__ again: a restart
    assert warm["instance0.cnt"] == 0       # the restart reset the program
    warm.retain_load(snap)
    warm.scan(1)
    assert [warm["instance0.cnt"], warm["instance0.kept.total"], warm["instance0.lost.total"]] \
        == [8, 8, 1]
    with pytest.raises(PlcError, match="checksum"):
        warm.retain_load(snap[:-1] + bytes([snap[-1] ^ 1]))
    warm.close()
