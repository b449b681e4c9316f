"""Real mode: the demo (`make run`) end to end, its failure path, and the programs with
OpenPLC's mbconfig.cfg (cycle policy: written and read every polling period) against the
emulator in static mode, as in a stock OpenPLC v3."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mipcosim import programs as L
from mipdemo import common as demo   # the demos' process and slave helpers
from mipdemo.logger import build_programs

REPO = Path(__file__).resolve().parents[2]

EMU = REPO / "build" / "emulator" / "mip-emulator"
if not EMU.is_file():
    pytest.fail("build/emulator/mip-emulator not built: run make first (these tests cannot run without it)", pytrace=False)


def run_demo(tmp_path, *args, timeout=300):
    return subprocess.run([sys.executable, str(REPO / "plc" / "demo.py"), "--rundir",
                           str(tmp_path / "run"), *args], capture_output=True, text=True,
                          timeout=timeout)


def leftover(rundir):
    """Processes still running with a file of rundir on their command line (from /proc, so
    no procps is needed)."""
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = next((l for l in (d / "status").read_text().splitlines()
                          if l.startswith("State:")), "")
        except OSError:
            continue
        if str(rundir) in cmd and "zombie" not in state:
            found.append(int(d.name))
    return found


def test_chain_demo_defaults_end_ok(tmp_path):
    p = run_demo(tmp_path)
    last = p.stdout.strip().splitlines()[-1]
    assert p.returncode == 0, p.stdout + p.stderr
    # the note's example: 5 records of 122 registers, record 2 lost once on its way up
    assert last.startswith("result: ok records=5 registers=610 polls=")
    assert "demo: radio lost 1 telegrams, 1 of them carrying a record" in p.stdout
    fields = dict(kv.split("=") for kv in last.split()[2:])
    assert set(fields) == {"records", "registers", "polls", "retransmissions", "duplicates",
                           "seconds"}
    assert int(fields["polls"]) > 0
    assert "read-out [" in p.stdout and "link: polls=" in p.stdout
    assert leftover(tmp_path / "run") == []


def _demo_of(tmp_path, n, cold):
    """The demo with n records; with cold, the runtime compiled anew (PLCRT_CACHE=off).
    Returns (output lines, seconds to the emulator's first line, seconds after it)."""
    env = dict(os.environ, PLCRT_CACHE="off") if cold else dict(os.environ)
    start = time.monotonic()
    p = subprocess.Popen([sys.executable, str(REPO / "plc" / "demo.py"), "--rundir",
                          str(tmp_path / f"run{n}"), "--records", str(n)],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    out, built = [], None
    for line in p.stdout:
        out.append(line)
        if built is None and line.startswith("demo: mip-emulator: listening"):
            built = time.monotonic()
    assert p.wait(timeout=300) == 0, "".join(out)
    return out, built - start, time.monotonic() - built


@pytest.mark.parametrize("n", [1, 2])
def test_chain_demo_of_one_or_two_records_claims_no_lost_record_2(tmp_path, n):
    """A transfer of 2 records is numbered 1, 16#FFFF on the radio, so the default scripted
    loss of record 2 cannot fire: the banner says so (it said "record 2 lost once", then
    "radio lost 0 telegrams"), in the singular for 1 record."""
    out, _, _ = _demo_of(tmp_path, n, cold=False)
    banner = next(l for l in out if "outstation(s) logging" in l)
    assert f"logging {n} record{'s' if n > 1 else ''} of 122 registers" in banner, banner
    assert "lost once" not in banner and "no record lost on purpose" in banner, banner
    assert "there is no record 2" in banner, banner
    assert "demo: radio lost 0 telegrams" in "".join(out)


@pytest.mark.slow   # a cold build of the runtime and both programs: about 20 s
def test_chain_demo_seconds_is_the_read_out_not_the_build(tmp_path):
    """seconds= is the read-out, not the build of the programs before it: a cold build
    tells the two apart."""
    out, build, after = _demo_of(tmp_path, 1, cold=True)
    seconds = float("".join(out).strip().splitlines()[-1].rsplit("seconds=", 1)[1])
    assert build > 2, "the build was not cold: the check below cannot tell"
    assert seconds <= after + 0.5, (seconds, build, after)


def test_chain_demo_two_stations_lossy(tmp_path):
    p = run_demo(tmp_path, "--stations", "2", "--records", "12", "--loss", "0.3", "--seed",
                 "5", "--per-transfer", "5", "--log-period-ms", "20", "--payload", "16")
    assert p.returncode == 0, p.stdout + p.stderr
    assert p.stdout.strip().splitlines()[-1].startswith("result: ok records=24 registers=384 ")


def test_chain_demo_failure_is_reported_and_cleaned_up(tmp_path):
    # 1 s is far too short for 400 records: the demo must say so and stop everything
    p = run_demo(tmp_path, "--records", "400", "--timeout", "1")
    assert p.returncode == 1
    assert p.stdout.strip().splitlines()[-1].startswith("result: FAIL timeout after 1 s")
    assert leftover(tmp_path / "run") == []


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_chain_demo_interrupted_stops_everything(tmp_path, sig):
    rundir = tmp_path / "run"
    p = subprocess.Popen([sys.executable, str(REPO / "plc" / "demo.py"), "--rundir", str(rundir),
                          "--records", "5000"], stdout=subprocess.PIPE, text=True)
    try:
        for line in p.stdout:
            if line.startswith("read-out ["):
                break
        assert leftover(rundir), "the demo's processes should be running now"
        p.send_signal(getattr(signal, sig))
        out = p.stdout.read()
        assert p.wait(timeout=30) == 1
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert out.strip().splitlines()[-1] == "result: FAIL interrupted"
    assert leftover(rundir) == []


def test_chain_demo_bad_option_one_line(tmp_path):
    p = run_demo(tmp_path, "--stations", "9")
    assert p.returncode == 2
    assert "--stations must be 1..4" in p.stderr and "Traceback" not in p.stderr


def test_chain_openplc_mbconfig_static_mode(tmp_path):
    """The committed plc/openplc/*.cfg, ports changed, with the cyclic-I/O flag; the programs
    built with the values of OpenPLC's matiec fork (stc --semantics=openplc), as OpenPLC runs
    them (PLCRT_SEMANTICS, when set, wins)."""
    progs = build_programs(tmp_path / "build",
                                semantics=os.environ.get("PLCRT_SEMANTICS") or "openplc")
    procs = demo.Procs()
    slaves = []
    try:
        p = procs.start("mip-emulator", [str(EMU), "--mdp-port", "0", "--trm-base-port", "0",
                                         "--mode", "static", "--static-registers", "123",
                                         "--bitrate", "1000000", "--slot-gap-ms", "1",
                                         "--loss-up", "0.1", "--loss-down", "0.1"],
                        tmp_path / "emu.log", stdout=subprocess.PIPE, text=True)
        fields = dict(kv.split("=", 1) for kv in p.stdout.readline().split()[2:])
        mdp, trm = fields["mdp"].rsplit(":", 1)[1], fields["trm"]
        cfg_out = (REPO / "plc/openplc/outstation-mbconfig.cfg").read_text().replace("15021", trm)
        cfg_cen = (REPO / "plc/openplc/central-mbconfig.cfg").read_text().replace("15020", mdp)
        (tmp_path / "out.cfg").write_text(cfg_out)
        (tmp_path / "cen.cfg").write_text(cfg_cen)
        ports = {}
        for role, cfg in (("central", "cen.cfg"), ("outstation", "out.cfg")):
            ports[role] = demo.free_port()
            procs.start(role, [str(progs[role].executable), "-c", str(tmp_path / cfg), "-s",
                               f"127.0.0.1:{ports[role]}"], tmp_path / f"{role}.log")
        cen, out = demo.Slave(ports["central"]), demo.Slave(ports["outstation"])
        slaves = [cen, out]
        for sl in slaves:
            sl.connect(time.monotonic() + 10)
        cyc = L.Params(records=6, payload=30, static=True, cyclic=True, timeout_ms=1500)
        cen.write(0, cyc.words())
        out.write(0, cyc.words())
        deadline = time.monotonic() + 120
        while out.read(L.peer_base(1) + L.S_ALL, 1)[0] != 1:
            procs.check_alive()
            assert time.monotonic() < deadline, "read-out did not finish"
            time.sleep(0.1)
        time.sleep(0.5)
        blk = cen.read(L.peer_base(1), 40)
        win = cen.read(L.peer_base(1) + L.W_BASE, L.WINDOW)
        # static mode: every record is the whole static block (122 registers after the
        # counter), the logger's 30 registers then zeros
        stream = []
        for n in range(1, 7):
            stream += L.log_record(n, 30, 1, 1) + [0] * 92
        committed = blk[L.R_COM_LO] + (blk[L.R_COM_HI] << 16)
        assert committed >= len(stream)
        # the last record may be followed by the one-record transfer's empty 16#FFFF block
        assert blk[L.R_TRANSFERS] == 1 and blk[L.R_FAILED] == 0
        full = stream + [0] * (committed - len(stream))
        positions = L.committed_positions(blk)
        assert len(positions) > 0
        assert [win[p % L.WINDOW] for p in positions] == [full[p] for p in positions]
    finally:
        for sl in slaves:
            sl.close()
        procs.stop()
