"""The whole chain in real time (make run RUN_ARGS=--chain): relay to control system (docs/chain.md).

mip-emulator with a relay (`--relay`, scripted events) -> the outstation soft-PLC
(plc/outstation_soe.st: MIP_SoeReader -> PLC_SoeLog -> MIP_Sender) -> the emulated radio -> the
central soft-PLC (plc/central_soe.st: MIP_Receiver, acknowledging after the hand-over ->
MIP_SoeServer) -> the SCADA stand-in (`mip-peer scada`, JSON lines). Shows the progress as the
demo does, then checks that every relay event arrived at the SCADA once, in order, with its
time stamp and value, and that the relay's recorder is empty; stops every process it started
and prints `result: ok events=N ...` (exit 0) or `result: FAIL <what differs>` (exit 1).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from mipcosim import chain as C
from mipprobe.sizing import handover_polls, handover_timeout_ms

from .common import (REPO, DemoError, Procs, Progress, Slave, TraceStats, bar, free_port,
                     fresh_rundir, modem_port_args, radio_args, result, run_or_fail,
                     start_emulator)


def parse_args(argv):
    p = argparse.ArgumentParser(prog="demo --chain", description=__doc__.splitlines()[0])
    p.add_argument("--chain", action="store_true", help="(this demo)")
    p.add_argument("--events", type=int, default=60, help="relay events (default 60)")
    p.add_argument("--every-ms", type=int, default=50, help="ms between two events (default 50)")
    p.add_argument("--per-record", type=int, default=15, help="relay entries per MIP record (1..15)")
    p.add_argument("--loss", type=float, default=0.0, help="telegram loss, each direction (default 0)")
    p.add_argument("--seed", type=int, default=1, help="seed of the radio and the events")
    p.add_argument("--realistic", action="store_true", help="9600 bit/s, 20 ms gaps")
    p.add_argument("--handover", choices=["pull", "push"], default="pull",
                   help="the central's hand-over: pull (MIP_SoeServer, polled by mip-peer scada; "
                        "default) or push (MIP_UnicosEvents to a redundant pair of mip-peer unicos)")
    p.add_argument("--scada-interval", type=float, default=0.1,
                   help="seconds between the SCADA's polls (default 0.1)")
    p.add_argument("--timeout", type=float, default=0, help="give up after this many seconds")
    p.add_argument("--fixed-ports", action="store_true",
                   help="the modems on the emulator's default ports (MDP-810 15020, TRM-810 "
                        "15021) instead of free ones, for a capture (docs/wireshark.md)")
    p.add_argument("--rundir", default=str(REPO / "build" / "plc" / "run-chain"),
                   help="programs, configs, logs, the events and the SCADA's file (default build/plc/run-chain)")
    a = p.parse_args(argv)
    if not 1 <= a.events <= 1_000_000:
        p.error("--events must be 1..1000000")
    if not 1 <= a.every_ms <= 60_000:
        p.error("--every-ms must be 1..60000")
    if not 1 <= a.per_record <= 15:
        p.error("--per-record must be 1..15 (8 registers an entry, 122 in a record)")
    if not 0 <= a.loss < 1:
        p.error("--loss must be in 0..1 (exclusive)")
    if not 0 < a.scada_interval <= 10:
        p.error("--scada-interval must be in (0, 10] s")
    return a


def build_programs(outdir, handover="pull"):
    from plcharness.build import BuildError, build_program
    res = {}
    for role, name in C.PROGRAMS.items():
        if role == "cen" and handover == "push":
            name = C.PUSH_PROGRAM
        try:
            res[role] = build_program(C.program_sources(role, handover), outdir / role)
        except BuildError as e:
            raise DemoError(f"building plc/{name}: {e}") from None
    return res


def blocks_timeout(a):
    """(the MIP blocks' tTimeout in ms, one line saying how it was sized): the radio's 300 ms
    (3000 ms on the realistic radio) and, the pull way, what the hand-over adds: the central
    acknowledges a record over the radio only once the SCADA took its last entry, 3 entries a
    poll (docs/serial.md's rule: mipprobe.sizing)."""
    from mippeer.scada import BLOCKS
    radio_ms = 3000 if a.realistic else 300
    if a.handover == "push":
        return radio_ms, (f"the MIP blocks' timeout {radio_ms} ms: the radio's; the push way's "
                          "hand-over adds no wait (the central writes each record to WinCC OA at once)")
    polls = handover_polls(a.per_record, BLOCKS)
    add = handover_timeout_ms(a.per_record, BLOCKS, a.scada_interval)
    return radio_ms + add, (
        f"the MIP blocks' timeout {radio_ms + add} ms: the radio's {radio_ms} ms + {add} ms for "
        f"the hand-over ({polls} SCADA polls every {a.scada_interval:g} s: a record of "
        f"{a.per_record} entries, {BLOCKS} a poll, and the poll it just missed; the central "
        f"acknowledges a record only once the SCADA took it)")


def relay_left(port):
    """The relay's count of entries not yet acknowledged (40601)."""
    from pymodbus.client import ModbusTcpClient
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=1)
    try:
        if not c.connect():
            raise DemoError(f"the relay on port {port} does not answer")
        rr = c.read_holding_registers(C.SOE_BASE, count=2)
        if rr.isError():
            raise DemoError(f"reading the relay's count: {rr}")
        return rr.registers[0]
    finally:
        c.close()


def run(a):
    rundir = fresh_rundir(a.rundir)
    push = a.handover == "push"
    print(f"demo: building plc/outstation_soe.st and plc/{C.PUSH_PROGRAM if push else 'central_soe.st'}"
          " ...", flush=True)
    progs = build_programs(rundir / "programs", a.handover)
    t_start = time.monotonic()
    events = C.script(a.events, start_s=1.0, every_s=a.every_ms / 1000, seed=a.seed)
    script = rundir / "events.txt"
    script.write_text("".join(f"{t:.3f} " + " ".join(f"{w:#06x}" for w in ws) + "\n"
                              for t, ws in events))
    radio = radio_args(a.realistic)
    procs = Procs()
    slaves = []
    try:
        trace = rundir / "emulator-trace.jsonl"
        line, fields = start_emulator(
            procs, rundir, modem_port_args(a.fixed_ports) + ["--stations", "1",
                            "--loss-up", str(a.loss), "--loss-down", str(a.loss),
                            "--seed", str(a.seed), "--trace", str(trace), "--lose-record", "0",
                            "--relay", f"0:origin={C.ORIGIN_MS},cap=1000,script={script}"] + radio)
        mdp_port = int(fields["mdp"].rsplit(":", 1)[1])
        trm_port = int(fields["trm"].split(",")[0])
        relay_port = int(fields["relay"].rsplit(":", 1)[-1])
        print(f"demo: {line}", flush=True)
        timeout_ms, sized = blocks_timeout(a)
        print(f"demo: {sized}", flush=True)
        params = C.SoeParams(per_record=a.per_record, timeout_ms=timeout_ms, redundant=push)
        cen_port = free_port()
        events_file = rundir / "unicos-events.jsonl"
        if push:
            # WinCC OA's redundant pair of UNICOS drivers (the stand-in), A active
            u = procs.start("UNICOS driver stand-in",
                            [sys.executable, "-m", "mippeer.unicos", "--port", "0", "--pair", "0",
                             "--marker", hex(C.UNICOS_MARKER), "--out", str(events_file)],
                            rundir / "unicos.log", stdout=subprocess.PIPE, text=True)
            uline = u.stdout.readline().strip()
            if not uline.startswith("mip-peer-unicos: listening"):
                procs.check_alive()
                raise DemoError(f"the UNICOS stand-in did not start: {uline!r}")
            uports = dict(kv.split("=") for kv in uline.split()[2:])
            print(f"demo: {uline}", flush=True)
            cen_conf = rundir / "central_push.conf"
            cen_conf.write_text(C.central_push_config(mdp_port, (int(uports["A"]), int(uports["B"]))))
            procs.start("central soft-PLC", [str(progs["cen"].executable), "-c", str(cen_conf),
                                             "-s", f"127.0.0.1:{cen_port}"], rundir / "central.log")
        else:
            cen_conf = rundir / "central_soe.conf"
            cen_conf.write_text(C.central_soe_config(mdp_port, cen_port))
            procs.start("central soft-PLC", [str(progs["cen"].executable), "-c", str(cen_conf)],
                        rundir / "central.log")
        out_port = free_port()
        out_conf = rundir / "outstation_soe.conf"
        out_conf.write_text(C.outstation_soe_config(trm_port, relay_port))
        procs.start("outstation soft-PLC", [str(progs["out"].executable), "-c", str(out_conf),
                                            "-s", f"127.0.0.1:{out_port}"], rundir / "outstation.log")
        deadline = time.monotonic() + 10
        central, outst = Slave(cen_port), Slave(out_port)
        for sl in (central, outst):
            sl.connect(deadline)
            slaves.append(sl)
        central.write(0, params.words())
        outst.write(0, params.words())
        # free ports, chosen at each start (the committed plc/*_soe.conf name fixed ones)
        cen_use = ("status words" if push else
                   "the SCADA polls it, the demo reads the status words")
        print(f"demo: ports (free ones): relay 127.0.0.1:{relay_port}, TRM-810 "
              f"127.0.0.1:{trm_port}, MDP-810 127.0.0.1:{mdp_port}, "
              + (f"UNICOS drivers A 127.0.0.1:{uports['A']} and B 127.0.0.1:{uports['B']}, "
                 if push else "")
              + f"the central soft-PLC's Modbus slave 127.0.0.1:{cen_port} ({cen_use}), the "
              f"outstation's 127.0.0.1:{out_port} (status words)", flush=True)
        entries = rundir / "scada-entries.jsonl"
        want = C.expected(events)
        dup_i = (C.PUSH_DUP if push else C.CEN_DUP) - C.CEN_RECORDS   # the receiver's duplicates
        if push:
            scada = None
            want_keys = {(w[3], w[4] // 10) for w in want}

            def pushed():
                """Events of the active driver (A) in the stand-in's file, in order."""
                if not events_file.exists():
                    return []
                rows = [json.loads(x) for x in events_file.read_text().splitlines() if x.strip()]
                return [r for r in rows if r.get("kind") == "event" and r["driver"] == "A"]
        else:
            scada = procs.start("SCADA stand-in",
                                [sys.executable, "-m", "mippeer.scada", "--port", str(cen_port),
                                 "--out", str(entries), "--entries", str(a.events),
                                 "--interval", str(a.scada_interval), "--retries", "100"],
                                rundir / "scada.log")
        print(f"demo: a relay with {a.events} events every {a.every_ms} ms, {a.per_record} per "
              f"record, over a {'realistic' if a.realistic else 'fast'} radio with {a.loss:.0%} "
              f"loss (seed {a.seed}), "
              + ("pushed to a redundant pair of UNICOS drivers" if push else
                 f"to a SCADA polling every {a.scada_interval:g} s"), flush=True)
        limit = a.timeout or (20 + events[-1][0] + a.events * (0.5 if a.realistic else 0.05)
                              / (1 - a.loss) ** 2)
        stats = TraceStats(trace)
        progress = Progress()

        def poll():
            if push or scada.poll() is None:
                procs.check_alive()
            stats.update()
            if push:
                got_push = pushed()
                taken = len({(r["value"] & 0xFFFF, r["ts_10ms"]) for r in got_push} & want_keys)
                done = taken >= a.events
            else:
                taken = sum(1 for _ in open(entries)) if entries.exists() else 0
                done = scada.poll() is not None
            stored = outst.read(C.OUT_STORED, 2)
            ob = outst.read(C.OUT_RETRANS, 1)[0]
            cb = central.read(C.CEN_RECORDS, 12)
            line1 = (f"relay -> {'WinCC OA' if push else 'SCADA'} {bar(min(taken, a.events), a.events)}  stored at the "
                     f"outstation={stored[0] | stored[1] << 16} records at the central="
                     f"{cb[0] | cb[1] << 16}")
            line2 = (f"link: polls={stats.polls} telegrams={stats.telegrams} lost={stats.lost} "
                     f"blocks={stats.blocks} retransmissions={ob} duplicates={cb[dup_i]} "
                     f"t={progress.elapsed():.1f}s")
            return line1, line2, done, f"{taken} of {a.events} events at the SCADA"
        progress.follow(poll, limit)
        if not push and scada.returncode != 0:
            tail = Path(rundir / "scada.log").read_text().strip().splitlines()[-1:]
            raise DemoError(f"the SCADA stand-in exited with {scada.returncode}: {' | '.join(tail)}")
        time.sleep(0.5)        # the last acknowledgement reaches the relay's side
        if push:
            # WinCC OA keeps no cause / type, and time stamps of 10 ms (docs/chain.md)
            got = [(r["value"] >> 16, r["offset"], None, r["value"] & 0xFFFF, r["ts_10ms"] * 10)
                   for r in pushed()]
            want = [(w[0], w[1], None, w[3], w[4] // 10 * 10) for w in want]
        else:
            rows = [json.loads(x) for x in entries.read_text().splitlines() if x.strip()]
            got = [(r["type_bit"], r["address"], r["cause_type"], r["value"], r["ts_ms"]) for r in rows]
        problems = []
        if got != want:
            dup = len(got) - len(set(got))
            missing = [i for i, e in enumerate(want) if e not in set(got)]
            first = next((i for i, (g, w) in enumerate(zip(got, want)) if g != w), min(len(got), len(want)))
            problems.append(f"the control system took {len(got)} entries, the relay had {len(want)} "
                            f"({len(missing)} missing, {dup} duplicated); the first difference at "
                            f"entry {first + 1}")
        left = relay_left(relay_port)
        if left:
            problems.append(f"the relay still holds {left} entries")
        cb = central.read(C.CEN_RECORDS, 12)
        return problems, dict(events=len(got), records=cb[0] | cb[1] << 16, polls=stats.polls,
                              lost=stats.lost, retransmissions=outst.read(C.OUT_RETRANS, 1)[0],
                              duplicates=cb[dup_i], seconds=round(time.monotonic() - t_start, 1))
    finally:
        for sl in slaves:
            sl.close()
        procs.stop()


def main(argv=None):
    a = parse_args(sys.argv[1:] if argv is None else argv)
    return result(
        run_or_fail(run, a),
        lambda r: (f"result: ok events={r['events']} records={r['records']} polls={r['polls']} "
                   f"lost_telegrams={r['lost']} retransmissions={r['retransmissions']} "
                   f"duplicates={r['duplicates']} seconds={r['seconds']}"))

