"""The chain demo (`make run`): a data logger read out over the emulated MIP radio network.

Starts mip-emulator (1 MDP-810 + N TRM-810 on 127.0.0.1, free ports), one outstation soft-PLC
per station (plc/outstation.st) and the central soft-PLC (plc/central.st) in real time, shows
the read-out, checks that the central holds the logger's data register for register, stops
every process it started and prints one last line `result: ok ...` (exit 0) or
`result: FAIL ...` (exit 1). plc/demo.py and `python -m mipdemo` run it (mipdemo.cli).
"""
from __future__ import annotations

import argparse
import sys
import time

from mipcosim import programs as L

from .common import (REPO, DemoError, Procs, Progress, Slave, TraceStats, bar, free_port,
                     fresh_rundir, modem_port_args, radio_args, result, run_or_fail,
                     start_emulator)

def parse_args(argv):
    p = argparse.ArgumentParser(prog="demo", description=__doc__.splitlines()[0])
    p.add_argument("--chain", action="store_true",
                   help="the whole chain instead (docs/chain.md): a relay's events over "
                        "both PLCs and the radio to a SCADA; `--chain --help` lists its options")
    p.add_argument("--records", type=int, default=5, help="logger records per station (default 5)")
    p.add_argument("--stations", type=int, default=1, help=f"outstations, 1..{L.MAX_STATIONS}")
    p.add_argument("--loss", type=float, default=0.0,
                   help="probability a telegram is lost, each direction (default 0)")
    p.add_argument("--lose-record", type=int, default=2,
                   help="the radio loses this record once on its way up, as in the note's "
                        "example (default 2; 0 = off)")
    p.add_argument("--seed", type=int, default=1, help="seed of the radio (default 1)")
    p.add_argument("--payload", type=int, default=122,
                   help="registers per record (1..122, default 122: the note's 126 less the "
                        "Modbus limit)")
    p.add_argument("--per-transfer", type=int, default=0,
                   help="records per transfer (default: all in one)")
    p.add_argument("--log-period-ms", type=int, default=100,
                   help="the logger writes a record every this many ms (default 100)")
    p.add_argument("--realistic", action="store_true",
                   help="realistic radio timing (9600 bit/s, 20 ms gaps) instead of fast")
    p.add_argument("--polled", action="store_true", help="polled drive instead of spontaneous")
    p.add_argument("--link", default="tcp",
                   help="PLC-to-modem link: tcp (default) or rtu:BAUD (Modbus RTU 8E1 on a pty "
                        "per modem, e.g. rtu:19200; docs/serial.md)")
    p.add_argument("--timeout", type=float, default=0,
                   help="give up after this many seconds (default: from the radio timing)")
    p.add_argument("--fixed-ports", action="store_true",
                   help="the emulator on its own default ports (MDP-810 15020, the TRM-810 of "
                        "station s 15020+s) instead of free ones: a capture filter and "
                        "Wireshark's dissector know them (docs/wireshark.md)")
    p.add_argument("--rundir", default=str(REPO / "build" / "plc" / "run"),
                   help="the programs, configs, logs and the emulator trace go here (default build/plc/run)")
    a = p.parse_args(argv)
    if not 1 <= a.stations <= L.MAX_STATIONS:
        p.error(f"--stations must be 1..{L.MAX_STATIONS}")
    if not 1 <= a.records <= 10_000_000:
        p.error("--records must be 1..10000000")
    if not 0 <= a.loss < 1:
        p.error("--loss must be in 0..1 (exclusive)")
    if not 0 <= a.lose_record <= 65535:
        p.error("--lose-record must be 0..65535")
    if not 1 <= a.payload <= 122:
        p.error("--payload must be 1..122")
    if a.per_transfer < 0 or a.per_transfer > 65534:
        p.error("--per-transfer must be 0..65534")
    if a.per_transfer == 0 and a.records > 65534:
        p.error("more than 65534 records: give --per-transfer")
    try:
        a.baud = L.parse_link(a.link)
    except ValueError as e:
        p.error(str(e))
    return a


def build_programs(outdir, semantics=None):
    """plc/outstation.st and plc/central.st built into outdir; semantics: stc --semantics
    (openplc for programs that run with OpenPLC's mbconfig.cfg; default PLCRT_SEMANTICS)."""
    from plcharness.build import BuildError, build_program
    res = {}
    for role in ("outstation", "central"):
        try:
            res[role] = build_program(L.program_sources(role, False), outdir / role,
                                      semantics=semantics)
        except BuildError as e:
            raise DemoError(f"building plc/{role}.st: {e}") from None
    return res


def lost_record_clause(a):
    """The banner's words on the scripted loss: the radio numbers a transfer's records 1, 2,
    ... and 16#FFFF for the last, so record r exists only in a transfer of more than r."""
    if not a.lose_record:
        return ""
    per = min(a.records, a.per_transfer) if a.per_transfer else a.records
    if a.lose_record == 0xFFFF or a.lose_record < per:
        return f", record {a.lose_record} lost once on its way up"
    return (f", no record lost on purpose (a transfer of {per} record{'s' if per != 1 else ''} "
            f"is numbered {', '.join(str(n) for n in range(1, min(per, 3)))}"
            f"{', ...' if per > 3 else ''}{', ' if per > 1 else ''}16#FFFF on the radio: "
            f"there is no record {a.lose_record})")


def run(a):
    rundir = fresh_rundir(a.rundir)
    print("demo: building plc/outstation.st and plc/central.st ...", flush=True)
    # into the run's own directory: two demos at once (tests side by side) must not replace
    # each other's programs while they run (the harness's cache makes a rebuild a copy)
    progs = build_programs(rundir / "programs")
    t_start = time.monotonic()   # seconds= is the read-out's time, not the build's
    radio = radio_args(a.realistic)
    # --link rtu:BAUD: every PLC reaches its modem over Modbus RTU on a pty the emulator makes
    # (the central the MDP-810, unit id = station; each outstation its TRM-810, unit id 1)
    rtu_args, serial = [], {}
    if a.baud:
        serial["mdp"] = rundir / "tty-mdp"
        rtu_args += ["--rtu", f"pty:{serial['mdp']}:{a.baud}:8E1=mdp"]
        for s in range(1, a.stations + 1):
            serial[s] = rundir / f"tty-trm{s}"
            rtu_args += ["--rtu", f"pty:{serial[s]}:{a.baud}:8E1=trm{s}@1"]
    procs = Procs()
    slaves = []
    try:
        trace = rundir / "emulator-trace.jsonl"
        line, fields = start_emulator(
            procs, rundir, modem_port_args(a.fixed_ports) + [
                            "--stations", str(a.stations), "--loss-up", str(a.loss),
                            "--loss-down", str(a.loss), "--seed", str(a.seed), "--trace", str(trace),
                            "--lose-record", str(a.lose_record)] + radio + rtu_args)
        mdp_port = int(fields["mdp"].rsplit(":", 1)[1])
        trm_ports = [int(x) for x in fields["trm"].split(",")]
        print(f"demo: {line}", flush=True)
        timeout_ms = 3000 if a.realistic else 300
        if a.baud:
            # on a serial line every Modbus exchange takes time: a 125-register read is
            # about 270 characters of 11 bits; the blocks' timeout covers eight of them
            timeout_ms += int(8 * 270 * 11 / a.baud * 1000)
        params = L.Params(records=a.records, per_transfer=a.per_transfer, payload=a.payload,
                          polled=a.polled, log_period_ms=a.log_period_ms, timeout_ms=timeout_ms)
        # central first, so the outstations find it listening
        cen_conf = rundir / "central.conf"
        # on a serial line the reads take the status words (and one data register: an
        # acknowledgement) until bit 0 shows a new block (status_first: measured best,
        # docs/serial.md)
        cen_conf.write_text(L.central_config(
            mdp_port, a.stations,
            serial=L.serial_keys(serial["mdp"], a.baud) if a.baud else None,
            status_first=L.RTU_STATUS_FIRST if a.baud else False))
        cen_port = free_port()
        procs.start("central soft-PLC", [str(progs["central"].executable), "-c", str(cen_conf),
                                         "-s", f"127.0.0.1:{cen_port}"], rundir / "central.log")
        out_ports = []
        for s in range(1, a.stations + 1):
            conf = rundir / f"outstation{s}.conf"
            conf.write_text(L.outstation_config(
                trm_ports[s - 1], serial=L.serial_keys(serial[s], a.baud) if a.baud else None,
                status_first=L.RTU_STATUS_FIRST if a.baud else False))
            port = free_port()
            out_ports.append(port)
            procs.start(f"outstation {s} soft-PLC", [str(progs["outstation"].executable), "-c",
                                                     str(conf), "-s", f"127.0.0.1:{port}"],
                        rundir / f"outstation{s}.log")
        deadline = time.monotonic() + 10
        central = Slave(cen_port)
        central.connect(deadline)
        slaves.append(central)
        outs = []
        for port in out_ports:
            sl = Slave(port)
            sl.connect(deadline)
            slaves.append(sl)
            outs.append(sl)
        central.write(0, L.Params(polled=a.polled, timeout_ms=timeout_ms).words())
        for s, sl in enumerate(outs, 1):
            params.station = s
            sl.write(0, params.words())
        print(f"demo: {a.stations} outstation(s) logging {a.records} "
              f"record{'s' if a.records != 1 else ''} of {a.payload} "
              f"registers, read out over a {'realistic' if a.realistic else 'fast'} radio "
              f"with {a.loss:.0%} loss (seed {a.seed})"
              + (f", PLCs on Modbus RTU at {a.baud} baud" if a.baud else "")
              + lost_record_clause(a),
              flush=True)
        total = a.records * a.stations
        limit = a.timeout or (30 + a.records * a.stations * (6.0 if a.realistic else 0.5)
                              / (1 - a.loss) ** 2 + a.records * a.log_period_ms / 1000)
        stats = TraceStats(trace)
        progress = Progress()
        counts = {}          # the last retransmissions= and duplicates= shown (the result's)

        def poll():
            procs.check_alive()
            stats.update()
            # progress: records the central has received (a transfer counts as read out
            # only when its last record arrived; the bar moves record by record)
            done = 0
            for s in range(1, a.stations + 1):
                lo, hi = central.read(L.peer_base(s) + L.R_REC_LO, 2)
                done += min(a.records, lo + (hi << 16))
            finished = all(sl.read(L.peer_base(1) + L.S_ALL, 1)[0] == 1 for sl in outs)
            retrans = sum(sl.read(L.peer_base(1) + L.S_RETRANS, 1)[0] for sl in outs)
            dups = sum(central.read(L.peer_base(s) + L.R_DUP, 1)[0]
                       for s in range(1, a.stations + 1))
            counts.update(retransmissions=retrans, duplicates=dups)
            line1 = f"read-out {bar(done, total)}"
            line2 = (f"link: polls={stats.polls} telegrams={stats.telegrams} lost={stats.lost} "
                     f"blocks={stats.blocks} blocks_lost={stats.blocks_lost} "
                     f"retransmissions={retrans} duplicates={dups} t={progress.elapsed():.1f}s")
            return line1, line2, finished, f"{done} of {total} records read out"
        progress.follow(poll, limit)
        time.sleep(0.5)      # let late duplicates show
        stats.update()
        # the check, register for register
        problems = []
        registers = 0
        for s in range(1, a.stations + 1):
            b = L.peer_base(s)
            blk = central.read(b, 40)
            win = central.read(b + L.W_BASE, L.WINDOW)
            stream = []
            for n in range(1, a.records + 1):
                stream += L.log_record(n, a.payload, params.session, s)
            committed = blk[L.R_COM_LO] + (blk[L.R_COM_HI] << 16)
            registers += committed
            if committed != len(stream):
                problems.append(f"station {s}: central holds {committed} registers, "
                                f"the logger wrote {len(stream)}")
            want_a, want_b = L.fletcher(stream)
            if (blk[L.R_SUM_A], blk[L.R_SUM_B]) != (want_a, want_b):
                problems.append(f"station {s}: checksum {blk[L.R_SUM_A]}/{blk[L.R_SUM_B]}, "
                                f"want {want_a}/{want_b}")
            for pos in L.committed_positions(blk):
                if pos >= len(stream):
                    break
                if win[pos % L.WINDOW] != stream[pos]:
                    problems.append(f"station {s}: register {pos} is {win[pos % L.WINDOW]}, "
                                    f"want {stream[pos]}")
                    break
            if blk[L.R_FAILED]:
                problems.append(f"station {s}: {blk[L.R_FAILED]} failed transfer(s) reported, "
                                f"last {L.error_name(blk[L.R_ERROR])}")
        return problems, dict(records=total, registers=registers, polls=stats.polls,
                              **counts,
                              seconds=round(time.monotonic() - t_start, 1),
                              lost_telegrams=stats.lost, lost_block_telegrams=stats.blocks_lost)
    finally:
        for sl in slaves:
            sl.close()
        procs.stop()


def main(argv=None):
    """The logger's demo; mipdemo.cli.main also runs the chain's (--chain)."""
    a = parse_args(sys.argv[1:] if argv is None else list(argv))
    return result(
        run_or_fail(run, a),
        lambda r: (f"result: ok records={r['records']} registers={r['registers']} "
                   f"polls={r['polls']} retransmissions={r['retransmissions']} "
                   f"duplicates={r['duplicates']} seconds={r['seconds']}"),
        note=lambda r: (f"demo: radio lost {r['lost_telegrams']} telegrams, "
                        f"{r['lost_block_telegrams']} of them carrying a record or an "
                        f"acknowledgement"))
