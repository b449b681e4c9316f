"""The Wireshark dissector dist/wireshark/mipmb.lua (docs/wireshark.md), run headless with tshark.

Captures of the demo (plc/demo.py: the example programs in soft-PLCs against mip-emulator over
Modbus TCP on 127.0.0.1) and of the co-simulation over TCP (mip-cosim --transport tcp) are
recorded with dumpcap in a network namespace of their own (only
the demo's traffic on its loopback), at test time; the counters tshark prints with the dissector
are compared with the emulator's own trace of the same run (--trace, emulator/README.md "Trace
format"), request for request and record for record. The expert info is tested on crafted
captures (pcapcraft.py): what no well-behaved PLC sends.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest
from mipcosim.trace import read_trace

from pcapcraft import Capture

REPO = Path(__file__).resolve().parents[2]
LUA = REPO / "dist" / "wireshark" / "mipmb.lua"
TSHARK = shutil.which("tshark")
DUMPCAP = shutil.which("dumpcap")
# CI installs tshark (.ci/apt-packages.txt): there its absence fails every test here, elsewhere
# the tests skip with the package to install
pytestmark = pytest.mark.skipif((TSHARK is None or DUMPCAP is None) and not os.environ.get("CI"),
                                reason="tshark is not installed (Debian package tshark)")

LOOPBACK_UP = ("import fcntl, socket, struct; fcntl.ioctl(socket.socket(), 0x8914, "
               "struct.pack('16sH22x', b'lo', 0x1 | 0x8 | 0x40))")      # SIOCSIFFLAGS: up
FIELDS = ["frame.number", "tcp.srcport", "tcp.dstport", "mbtcp.trans_id", "modbus.func_code",
          "mipmb.device", "mipmb.station", "mipmb.kind", "mipmb.read_status", "mipmb.record",
          "mipmb.ack", "mipmb.len", "mipmb.old_counter", "mipmb.no_new_data", "mipmb.hop",
          "_ws.col.Info", "_ws.expert.message"]


def tshark(pcap, *args, lua=True, check=True):
    cmd = [TSHARK, "-r", str(pcap)] + (["-X", f"lua_script:{LUA}"] if lua else []) + list(args)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120,
                       env={"PATH": "/usr/bin:/bin", "HOME": "/nonexistent", "MIPMB_DEBUG": "1"})
    if check:
        assert r.returncode == 0, r.stderr
    # the dissector never fails a frame (MIPMB_DEBUG: it would say so here)
    assert "mipmb:" not in r.stderr and "Lua" not in r.stderr, r.stderr
    return r.stdout


def rows(pcap, *opts, lua=True, display="mipmb"):
    out = tshark(pcap, *opts, "-Y", display, "-T", "fields", "-E", "separator=\t",
                 "-E", "occurrence=a", "-E", "aggregator=|",
                 *[x for f in FIELDS for x in ("-e", f)], lua=lua)
    return [dict(zip(FIELDS, line.split("\t"))) for line in out.splitlines() if line.strip()]


def captured(tmp: Path, command: str):
    """Output of a shell command run in a network namespace of its own, while dumpcap records
    every TCP frame on its loopback to tmp/capture.pcapng."""
    pcap, out, log = tmp / "capture.pcapng", tmp / "command.out", tmp / "dumpcap.log"
    script = f"""
{sys.executable} -c "{LOOPBACK_UP}"
{DUMPCAP} -q -i lo -f tcp -w {pcap} 2>{log} &
D=$!
for i in $(seq 100); do grep -q '^File:' {log} && break; sleep 0.1; done
{command} >{out} 2>&1
st=$?
sleep 0.3; kill -INT $D; wait $D
exit $st
"""
    r = subprocess.run(["unshare", "-rn", "sh", "-c", script], cwd=REPO, timeout=600,
                       capture_output=True, text=True)
    text = out.read_text() if out.exists() else ""
    assert r.returncode == 0, f"{r.stderr}\n{text}\n{log.read_text() if log.exists() else ''}"
    assert "result: ok" in text, text
    return pcap, text


def run_demo(tmp: Path, *demo_args):
    """(pcap, trace, ports {port: (ep, station)}) of one demo run, captured on its own loopback."""
    rundir = tmp / "run"
    pcap, text = captured(tmp, f"{sys.executable} {REPO}/plc/demo.py --rundir {rundir} "
                               + " ".join(demo_args))
    m = re.search(r"listening mdp=127\.0\.0\.1:(\d+) trm=([\d,]+)", text)
    ports = {int(m.group(1)): ("mdp", None)}
    for s, p in enumerate(m.group(2).split(","), 1):
        ports[int(p)] = ("trm", s)
    return pcap, read_trace(rundir / "emulator-trace.jsonl"), ports


def run_cosim(tmp: Path, *args):
    """The same of one co-simulation run over real TCP on 127.0.0.1 (mip-cosim --transport
    tcp, one station): the servers' ports are those of the connections' SYNs, the modem on
    each is what the dissector says it is (the test then checks every request of it)."""
    trace = tmp / "trace.jsonl"
    cosim = Path(sys.executable).parent / "mip-cosim"
    pcap, _ = captured(tmp, f"{cosim} run --transport tcp --workdir {tmp / 'w'} "
                            f"--trace {trace} " + " ".join(args))
    syn = tshark(pcap, "-Y", "tcp.flags.syn == 1 && tcp.flags.ack == 0", "-T", "fields",
                 "-e", "tcp.dstport", lua=False).split()
    opts = ["-o", f"mipmb.ports:{','.join(syn)}"]
    ports = {}
    for port in syn:
        devs = {r["mipmb.device"] for r in rows(pcap, *opts, display=f"mipmb && tcp.dstport == {port}")}
        assert len(devs) == 1, (port, devs)
        ports[int(port)] = ("trm", 1) if devs.pop().startswith("TRM") else ("mdp", None)
    assert sorted(ports.values(), key=str) == [("mdp", None), ("trm", 1)]
    return pcap, read_trace(trace), ports


def port_opts(ports):
    p = ",".join(str(x) for x in sorted(ports))
    # ours, and the Modbus/TCP dissector's own (it tells requests from responses by the port)
    return ["-o", f"mipmb.ports:{p}", "-o", f"mbtcp.tcp.port:{p}"]


def compare_with_trace(pcap, trace, ports):
    """Every request the emulator traced is in the capture, labelled with the modem it went to
    and, for a block, the counter the trace has; every new block read carries the counter the
    radio delivered. Returns the number of records compared."""
    rs = rows(pcap, *port_opts(ports))
    assert not [r for r in rs if r["_ws.expert.message"]], "expert info on a clean run"
    # the emulator traces a request when it answers it: a request still on its way when the
    # emulator stopped (the end of a demo on a loaded machine) is in the capture only
    answered = set()
    for line in tshark(pcap, *port_opts(ports)[2:], "-Y", "mbtcp", "-T", "fields",
                       "-e", "tcp.srcport", "-e", "tcp.dstport", "-e", "mbtcp.trans_id",
                       lua=False).splitlines():
        src, dst, tid = (int(x) for x in line.split("\t")[:3])
        if src in ports:
            answered.add((src, tid))
    # requests, per modem and station: (tid, fc) and the counter of each block written
    got, want = defaultdict(list), defaultdict(list)
    for r in rs:
        if "request" not in r["mipmb.kind"]:
            continue
        if (int(r["tcp.dstport"]), int(r["mbtcp.trans_id"])) not in answered:
            continue
        ep, st = ports[int(r["tcp.dstport"])]
        assert r["mipmb.device"].startswith("TRM" if ep == "trm" else "MDP"), r
        if ep == "mdp":
            st = int(r["mipmb.station"])
        counter = r["mipmb.record"] or r["mipmb.ack"]
        got[ep, st].append((int(r["mbtcp.trans_id"]), int(r["modbus.func_code"]),
                            int(counter) if counter else None))
    for e in trace:
        if e["ev"] == "modbus":
            assert e["exc"] == 0, e
            write_start = 2001 if e["ep"] == "trm" else 10
            counter = e.get("w0") if e.get("wa") == write_start else None
            want[e["ep"], e["st"]].append((e["tid"], e["fc"], counter))
    assert dict(got) == dict(want)
    # every read: the new-data bit and the counter of the block in the read area, as the trace
    # has them at that read (the last block the radio delivered there, and whether one came
    # since the last read of the data area; emulator/README.md "New read data")
    area = {("trm", 0): (2198, 2200), ("mdp", 0): (198, 200)}
    block, new = defaultdict(int), defaultdict(bool)
    want_reads, got_reads = defaultdict(list), defaultdict(list)
    for e in trace:
        if e["ev"] == "radio" and e["regs"] > 0 and not e["lost"] and e["kind"] in ("poll", "answer"):
            ep = "mdp" if e["dir"] == "up" else "trm"
            block[ep, e["st"]], new[ep, e["st"]] = e["r0"], True
        elif e["ev"] == "modbus" and "ra" in e:
            k = (e["ep"], e["st"])
            status, data = area[e["ep"], 0]
            end = e["ra"] + e["rq"]
            if e["ra"] <= status < end and e["ra"] <= data < end:
                want_reads[k].append((e["tid"], new[k], block[k]))
            if e["ra"] < data + 148 and end > data:
                new[k] = False
    for r in rs:
        if r["mipmb.kind"] == "read response" and r["mipmb.read_status"]:
            ep, st = ports[int(r["tcp.srcport"])]
            if ep == "mdp":
                st = int(r["mipmb.station"])
            fresh = bool(int(r["mipmb.read_status"].split("|")[0], 16) & 1)
            # a read without new data shows the block read before, as such: no record, no ack
            counter = (r["mipmb.record"] if ep == "mdp" else r["mipmb.ack"]) if fresh \
                else r["mipmb.old_counter"]
            assert bool(r["mipmb.no_new_data"]) != fresh, r
            if not fresh:
                assert not r["mipmb.record"] and not r["mipmb.ack"], r
            got_reads[ep, st].append((int(r["mbtcp.trans_id"]), fresh, int(counter)))
    assert dict(got_reads) == dict(want_reads)
    assert all(any(fresh for _, fresh, _ in v) for v in want_reads.values())
    return sum(1 for k, v in got.items() for t in v if k[0] == "trm" and t[2] is not None)


@pytest.fixture(scope="module")
def demo3(tmp_path_factory):
    """One demo run of 3 records (record 2 lost once on its way up), captured: shared by the
    tests that read it (a run takes ~10 s)."""
    return run_demo(tmp_path_factory.mktemp("demo3"), "--records", "3")


def test_demo_capture_counters_are_the_emulators(demo3):
    """The note's example (record 2 lost once on its way up), 3 records: tshark with the
    dissector prints every request's modem and every block's counter as the emulator traced
    them, the records 1, 2, 16#FFFF and their acknowledgements in order."""
    pcap, trace, ports = demo3
    assert compare_with_trace(pcap, trace, ports) == 3
    rs = rows(pcap, *port_opts(ports), display='mipmb.kind == "write request"')
    assert [(r["mipmb.device"].split()[0], r["mipmb.record"] or r["mipmb.ack"]) for r in rs] == [
        ("MDP-810", "0"), ("TRM-810", "1"), ("MDP-810", "1"), ("TRM-810", "2"),
        ("MDP-810", "2"), ("TRM-810", "65535"), ("MDP-810", "65535")]
    # the Modbus/TCP dissector alone has the frames, but no record counters
    assert rows_plain(pcap, port_opts(ports)[2:])
    r = subprocess.run([TSHARK, "-r", str(pcap), "-Y", "mipmb.record"], capture_output=True,
                       text=True, env={"PATH": "/usr/bin:/bin", "HOME": "/nonexistent"})
    assert r.returncode != 0 and "mipmb.record" in r.stderr


def test_demo_capture_details_read_right(demo3):
    """What a field engineer reads in Wireshark on a capture of the demo: every counter a
    number, 0 and 16#FFFF named, none "Unknown"; a read with status bit 0 clear (no new data,
    note 3.1.1 / 3.2.1) says so and carries no record or acknowledgement label; each item says
    which way its frame and its block go."""
    pcap, trace, ports = demo3
    details = tshark(pcap, *port_opts(ports), "-O", "mipmb", "-Y", "mipmb")   # our tree only
    assert "Unknown" not in details, [x for x in details.splitlines() if "Unknown" in x][:5]
    for text in ("Record counter: 1 (the outstation's record 1; radio outstation->central)",
                 "Record counter: 65535 (16#FFFF: the last record of the outstation; "
                 "radio outstation->central)",
                 "Acknowledgement counter: 0 (start: no record received yet by the central "
                 "from the outstation; radio central->outstation)",
                 "Acknowledgement counter: 2 (the central acknowledges the outstation's record 2; "
                 "radio central->outstation)",
                 "Direction: central PLC -> MDP-810", "Direction: MDP-810 -> central PLC",
                 "Direction: outstation PLC -> TRM-810", "Direction: TRM-810 -> outstation PLC"):
        assert text in details, text
    reads = [r for r in rows(pcap, *port_opts(ports)) if r["mipmb.kind"] == "read response"
             and r["mipmb.read_status"]]
    stale = [r for r in reads if not int(r["mipmb.read_status"].split("|")[0], 16) & 1]
    fresh = [r for r in reads if r not in stale]
    assert stale and fresh       # the PLCs poll faster than blocks arrive: both kinds are there
    for r in stale:
        assert "[MIP read, no new data]" in r["_ws.col.Info"], r
        assert not re.search(r"record|ack", r["_ws.col.Info"]), r
    # a record is labelled on the central's reads only as often as the radio brought it
    delivered = defaultdict(int)
    for e in trace:
        if e["ev"] == "radio" and e["dir"] == "up" and e["regs"] > 0 and not e["lost"]:
            delivered[e["r0"]] += 1
    labelled = defaultdict(int)
    for r in fresh:
        if ports[int(r["tcp.srcport"])][0] == "mdp":
            m = re.search(r"\[MIP record (\d+|16#FFFF)\]", r["_ws.col.Info"])
            assert m, r
            labelled[65535 if m.group(1) == "16#FFFF" else int(m.group(1))] += 1
    assert set(labelled) == {1, 2, 65535}
    assert all(n <= delivered[rec] for rec, n in labelled.items()), (labelled, delivered)


def rows_plain(pcap, opts):
    return tshark(pcap, *opts, "-Y", "modbus.func_code == 16", "-T", "fields",
                  "-e", "modbus.func_code", lua=False).split()


def test_cosim_tcp_capture_under_loss(tmp_path):
    """The chain in co-simulation with the PLCs' Modbus over TCP, 10 % loss: the same
    comparison with the emulator core's trace."""
    pcap, trace, ports = run_cosim(tmp_path, "--records", "5", "--loss", "0.1", "--seed", "3")
    assert compare_with_trace(pcap, trace, ports) >= 5


@pytest.mark.slow
def test_demo_capture_two_stations_under_loss(tmp_path):
    """Three outstations, 40 records each, 25 % loss both ways: blocks repeated and delivered
    twice on the radio, acknowledgements written again; the counters still match the trace
    record for record (a few thousand requests)."""
    pcap, trace, ports = run_demo(tmp_path, "--stations", "3", "--records", "40",
                                  "--loss", "0.25", "--seed", "5")
    assert compare_with_trace(pcap, trace, ports) >= 3 * 40


# crafted captures ---------------------------------------------------------------------------

TRM, MDP = 15021, 15020


def experts(pcap, *opts):
    """{frame: expert message} of the dissector's expert info."""
    out = {}
    for r in rows(pcap, "-o", f"mipmb.ports:{MDP},{TRM}", "-o", f"mbtcp.tcp.port:{MDP},{TRM}",
                  *opts):
        if r["_ws.expert.message"]:
            out[int(r["frame.number"])] = r["_ws.expert.message"]
    return out


def test_expert_info_for_what_the_note_forbids(tmp_path):
    c = Capture()
    c.write(TRM, 1, 2001, [1, 11, 12])                      # frames 1, 2
    c.write(TRM, 1, 2001, [2, 21, 22])                      # 3, 4
    c.write(TRM, 1, 2001, [3, 31, 32])                      # 5, 6
    back = c.write(TRM, 1, 2001, [2, 21, 22])[0]            # 7: 3 -> 2 goes backwards
    never = c.read(TRM, 1, 2198, [0x0001, 1, 7])[1]         # 10: new data, ack 7 > 3 sent
    stale = c.read(TRM, 1, 2198, [0x0000, 1, 9])[1]         # 12: no new data: not judged
    skip = c.write(TRM, 1, 2001, [5, 51], fc=23)[0]         # 13: 2 -> 5 skips (FC23 write)
    c.write(TRM, 1, 2001, [65535, 1])                       # 15: last record
    c.write(TRM, 1, 2001, [1, 1])                           # 17: a new transfer
    c.read(TRM, 1, 2198, [0x0001, 1, 65535])                # 19/20: the old 0xFFFF, fine
    # the central's side: acknowledgements it writes against the records it read as new, each
    # request over a new TCP connection (the link is the modem's address, port and unit id)
    c.write(MDP, 3, 10, [0])                                # 21
    c.reconnect(MDP)
    c.read(MDP, 3, 198, [0x0001, 2, 1, 0])                  # 23/24: record 1 arrived
    c.reconnect(MDP)
    c.write(MDP, 3, 10, [1])                                # 25
    c.reconnect(MDP)
    mdp_never = c.write(MDP, 3, 10, [4])[0]                 # 27: record 4 never arrived
    c.reconnect(MDP)
    mdp_back = c.write(MDP, 3, 10, [2])[0]                  # 29: 4 -> 2, and 2 never arrived
    c.reconnect(MDP)
    c.write(MDP, 4, 10, [3])                                # 31: station 4 has its own counters
    pcap = c.save(tmp_path / "forbidden.pcap")
    got = experts(pcap)
    assert set(got) == {back, never, skip, mdp_never, mdp_back}, got
    assert got[back] == "counter went back to 2"
    assert got[never] == "acknowledges 7, a record not sent in this transfer"
    assert got[skip] == "record 5 skips a number"
    assert got[mdp_never] == "acknowledges 4, a record not sent in this transfer"
    assert got[mdp_back] == "counter went back to 2"
    assert stale not in got
    # judged once, in frame order: tshark's two passes (and Wireshark revisiting frames) agree
    two = tshark(pcap, "-2", "-o", f"mipmb.ports:{MDP},{TRM}", "-o", f"mbtcp.tcp.port:{MDP},{TRM}",
                 "-T", "fields", "-e", "frame.number", "-e", "_ws.expert.message")
    assert {int(n): m for n, m in (line.split("\t") for line in two.splitlines()) if m} == got
    # the filter names a user types
    out = tshark(pcap, "-o", f"mipmb.ports:{MDP},{TRM}", "-Y",
                 "mipmb.counter_backwards || mipmb.ack_never_sent || mipmb.record_skipped",
                 "-T", "fields", "-e", "frame.number")
    assert [int(x) for x in out.split()] == sorted(got)


def test_registers_labelled_and_unknown_ones_left_alone(tmp_path):
    c = Capture()
    status = c.read(TRM, 1, 2198, [0x0013, 3, 65535, 8, 9])[1]   # bits 0, 1, 4; count 3
    mdp = c.read(MDP, 2, 0, [0x4837, 0x0005, 0x0010, 0, 2, 0, 0, 0, 0, 3])[1]
    unknown = c.read(TRM, 1, 1000, [1, 2, 3])                  # not a MIP register
    c.raw(TRM, 1, b"\x10\x07")                                  # a truncated FC16: skipped
    c.raw(MDP, 1, b"\x03\x00\xc6\x00\x02", b"\x83\x02")        # an exception answer
    pcap = c.save(tmp_path / "regs.pcap")
    out = tshark(pcap, "-o", f"mipmb.ports:{MDP},{TRM}", "-V", "-Y", f"frame.number == {status}")
    for text in ("Modem: TRM-810 (outstation)", "Bit 0 new read data: True",
                 "Bit 1 write data waiting: True", "Bit 4 write data unconfirmed: True",
                 "Number of registers received: 3",
                 "Direction: TRM-810 -> outstation PLC",
                 "Acknowledgement counter: 65535 (the central acknowledges the outstation's last "
                 "record (16#FFFF); radio central->outstation)"):
        assert text in out, (text, out)
    out = tshark(pcap, "-o", f"mipmb.ports:{MDP},{TRM}", "-V", "-Y", f"frame.number == {mdp}")
    for text in ("Station (MDP unit id): 2", "Station hears the MDP at -dBm: 72",
                 "MDP hears the station at -dBm: 55", "Station status: 0x0005",
                 "Read status: 0x0010", "Number of registers received: 2",
                 "Number of write registers: 3"):
        assert text in out, (text, out)
    labelled = [int(r["frame.number"]) for r in rows(pcap, "-o", f"mipmb.ports:{MDP},{TRM}")]
    assert not set(unknown) & set(labelled)
    assert labelled == [1, 2, 3, 4, 8]           # the request of the exception, not its answer


def test_preferences_one_based_and_bidirectional(tmp_path):
    c = Capture()
    c.write(TRM, 1, 2000, [4, 3, 99])        # a modem counting from 1: 2001 is address 2000
    c.read(TRM, 1, 2197, [0x0001, 2, 3, 5])
    pcap = c.save(tmp_path / "onebased.pcap")
    base = ["-o", f"mipmb.ports:{MDP},{TRM}"]
    assert [r["mipmb.record"] for r in rows(pcap, *base, "-o", "mipmb.one_based:TRUE",
                                            display="mipmb.record")] == ["4"]
    assert rows(pcap, *base, display="mipmb.record") == []     # 0-based: 2000 is the count
    bidi = rows(pcap, *base, "-o", "mipmb.one_based:TRUE", "-o", "mipmb.bidi:TRUE",
                display="mipmb.record || mipmb.ack")
    assert [(r["mipmb.record"], r["mipmb.ack"]) for r in bidi] == [("4", "3"), ("5", "3")]
    # other register bases: a modem whose map sits elsewhere
    c = Capture()
    c.write(TRM, 1, 3001, [7, 1])
    c.read(TRM, 1, 3198, [0x0001, 1, 6])
    moved = c.save(tmp_path / "moved.pcap")
    opts = [*base, "-o", "mipmb.trm_write:3001", "-o", "mipmb.trm_status:3198"]
    assert [(r["mipmb.record"], r["mipmb.ack"]) for r in rows(moved, *opts)] == \
        [("7", ""), ("", ""), ("", "6")]       # write, read request, read response
    assert rows(moved, *base) == []
    # the port preference: a port not in it is not the modem's
    assert rows(pcap, "-o", "mipmb.ports:502", "-o", "mipmb.one_based:TRUE") == []
