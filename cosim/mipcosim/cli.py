"""mip-cosim: run the logger link (outstations, radio, central) in co-simulation from the command
line; `soak` is the long run.

    python -m mipcosim.cli run  [--records N] [--loss P] [--seed S] [--bidi] [--static] [--polled]
    python -m mipcosim.cli soak [--records 100000] [--loss 0.3] [--restart-every 120] [--warm] ...
    python -m mipcosim.cli run|soak --chain ...     (issue 35's chain: mipcosim/chaincli.py)

Both print the delivery counts and end with one line `result: ok ...` (exit 0) or
`result: FAIL ...` (exit 1).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from .check import check, summary
from . import programs as L
from . import result
from .sim import SEC, LoggerLink, CosimError, Radio, Setup


def parse(argv):
    p = argparse.ArgumentParser(prog="mip-cosim", description=" ".join(__doc__.split("\n\n")[0].split()))
    p.add_argument("what", choices=["run", "soak"])
    p.add_argument("--records", type=int, help="records per sender (run: 5, soak: 100000)")
    p.add_argument("--per-transfer", type=int, help="records per transfer (run: all, soak: 500)")
    p.add_argument("--loss", type=float, help="telegram loss per direction (run: 0.1, soak: 0.3)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--stations", type=int, default=1)
    p.add_argument("--payload", type=int, default=16)
    p.add_argument("--bidi", action="store_true")
    p.add_argument("--static", action="store_true")
    p.add_argument("--polled", action="store_true")
    p.add_argument("--realistic", action="store_true", help="9600 bit/s, 20 ms gaps")
    p.add_argument("--window", type=int, choices=[1, 2], default=1,
                   help="the senders' uWindow (MIP_Sender, MIP_Link): 2 pipelines the records "
                        "(st_lib/PROTOCOL.md P27); with --bidi (MIP_Link) the "
                        "senders run window 1 (the result line says which window they ran)")
    p.add_argument("--restart-every", type=float,
                   help="virtual seconds between PLC restarts, alternating outstation / central "
                        "(run: none, soak: 120)")
    p.add_argument("--warm-restarts", "--warm", dest="warm", action="store_true",
                   help="warm restarts: the blocks wait for a snapshot before each new "
                        "record and acknowledgement (flag bit 3); a restarted PLC comes back with "
                        "its last snapshot (kill -9), every third one after a snapshot at the "
                        "stop (graceful); demands: lost 0, duplicated 0, no failure; default cold "
                        "restarts (soak: a restart every 60 s instead of 120)")
    p.add_argument("--limit", type=float, default=0, help="virtual seconds before giving up")
    p.add_argument("--trace", help="emulator trace (JSON lines) to this file")
    p.add_argument("--transport", choices=["inproc", "socketpair", "tcp"], default="inproc",
                   help="PLC <-> emulator: the kernel's in-process transport (default) or "
                        "libmodbus over socketpairs or TCP on 127.0.0.1")
    p.add_argument("--tick-ms", type=int, default=10, help="scan tick (the programs' task interval)")
    p.add_argument("--link", default="tcp",
                   help="PLC-to-modem link: tcp (default) or rtu:BAUD, Modbus RTU 8E1 whose "
                        "character time counts in virtual time (docs/serial.md)")
    p.add_argument("--workdir", help="build and scratch directory (default: a temp dir)")
    a = p.parse_args(argv)
    soak = a.what == "soak"
    a.records = a.records if a.records is not None else (100_000 if soak else 5)
    a.per_transfer = a.per_transfer if a.per_transfer is not None else (500 if soak else 0)
    a.loss = a.loss if a.loss is not None else (0.3 if soak else 0.1)
    a.restart_every = a.restart_every if a.restart_every is not None else (
        (60 if a.warm else 120) if soak else 0)
    if a.window == 2 and (a.static or a.polled):
        p.error("--window 2: the pipelined sender is for dynamic mode and spontaneous drive "
                "(st_lib/PROTOCOL.md P27)")
    if a.per_transfer == 0 and a.records > 65534:
        p.error("more than 65534 records need --per-transfer")
    if not 1 <= a.stations <= L.MAX_STATIONS:
        p.error(f"--stations must be in 1..{L.MAX_STATIONS} (the receivers of plc/central.st)")
    if not 1 <= a.tick_ms <= 1000:
        p.error("--tick-ms must be in 1..1000")
    if not 0 <= a.loss < 1:
        p.error("--loss must be in 0..1 (exclusive)")
    try:
        a.baud = L.parse_link(a.link)
    except ValueError as e:
        p.error(str(e))
    if a.baud and a.transport != "inproc":
        p.error("--link rtu:BAUD needs --transport inproc")
    return a



def link_timeout_ms(baud):
    """What a serial link adds to the blocks' timeout: eight 125-register exchanges (about 270
    characters of 11 bits each); 0 for TCP. The demo (plc/demo.py) adds the same."""
    return int(8 * 270 * 11 / baud * 1000) if baud else 0


def main(argv=None):
    args = sys.argv[1:] if argv is None else list(argv)
    if "--chain" in args:            # relay -> PLCs -> radio -> SCADA (mipcosim/chaincli.py)
        from .chaincli import main as chain_main
        return chain_main(args)
    a = parse(argv)
    st = Setup(stations=a.stations, static=a.static, polled=a.polled, bidi=a.bidi, loss=a.loss,
               seed=a.seed, records=a.records, per_transfer=a.per_transfer, payload=a.payload,
               radio=Radio.realistic() if a.realistic else Radio(),
               timeout_ms=(3000 if a.realistic else 300) + link_timeout_ms(a.baud),
               transport=a.transport, tick_ms=a.tick_ms, retain=a.warm, window=a.window,
               link_baud=a.baud, status_first=L.RTU_STATUS_FIRST if a.baud else False)
    workdir = Path(a.workdir or tempfile.mkdtemp(prefix="mipcosim-"))
    limit = a.limit or (60 + a.records * a.stations * (8 if a.realistic else 0.5)
                        / (1 - a.loss) ** 2)
    t0 = time.monotonic()
    try:
        with LoggerLink(st, workdir, trace=a.trace) as ch:
            kind = "warm" if a.warm else "cold"
            restarts = f", a {kind} restart every {a.restart_every:g} s" if a.restart_every else ""
            print(f"mip-cosim: {a.what}: {a.stations} station(s), {a.records} records each, "
                  f"loss {a.loss:.0%}, seed {a.seed}, {'bidirectional' if a.bidi else 'uni'}, "
                  f"{'static' if a.static else 'dynamic'}, {'polled' if a.polled else 'spontaneous'}"
                  f"{', window 2' if a.window == 2 else ''}{restarts}"
                  f"{f', PLCs on Modbus RTU at {a.baud} baud' if a.baud else ''}",
                  flush=True)
            next_restart = a.restart_every * SEC if a.restart_every else None
            k = 0
            finished = False
            last_report = 0.0
            while ch.now < limit * SEC:
                ch.run_for(SEC)
                if next_restart is not None and ch.now >= next_restart and not ch.finished():
                    who = ("out", 1 + (k // 2) % a.stations) if k % 2 == 0 else ("cen", 0)
                    ch.restart(who, warm=a.warm, graceful=a.warm and k % 3 == 2)
                    k += 1
                    next_restart += a.restart_every * SEC
                if time.monotonic() - last_report > 10:
                    b = L.peer_base(1)
                    out = sum(ch.mw(("out", s), b + L.S_OUT_LO) + (ch.mw(("out", s), b + L.S_OUT_HI) << 16)
                              for s in range(1, a.stations + 1))
                    print(f"  t={ch.now / SEC:.0f}s virtual, {time.monotonic() - t0:.0f}s wall: "
                          f"{out}/{a.records * a.stations} records read out, {k} restarts",
                          flush=True)
                    last_report = time.monotonic()
                if ch.finished():
                    ch.run_for(3 * SEC)
                    finished = True
                    break
            reps = check(ch)
            tot = summary(reps)
            radio = ch.radio_stats()
            wall = time.monotonic() - t0
            for r in reps:
                print(f"  {r.name}: transfers={r.transfers} records={r.records} "
                      f"done={r.done} failed_reported={dict(r.failed)} cut_by_restart={r.cut} "
                      f"receiver_reported={dict(r.receiver_failures)} "
                      f"delivered_after_failure={r.delivered_after_failure} "
                      f"duplicated={r.duplicated_records} lost={r.lost}")
                for p in r.problems[:10]:
                    print(f"    problem: {p}")
            print(f"  radio: polls={radio['polls']} telegrams={radio['tel_up'] + radio['tel_down']} "
                  f"lost={radio['lost_up'] + radio['lost_down']} link duplicates="
                  f"{radio['dup_up'] + radio['dup_down']}; {radio['scans']} scans, "
                  f"{radio['requests']} Modbus requests; {ch.now / SEC:.0f} s virtual in "
                  f"{wall:.0f} s wall")
            rs = ch.retain_stats()
            print(f"  retain: {rs['snapshots']} snapshots, {rs['warm_restarts']} warm restarts "
                  f"({rs['restored']} restored a snapshot, the others had nothing retained)")
            failed = tot.get('failed_reported', 0) + tot.get('cut_by_restart', 0)
            # the window the senders ran, from their own state (MIP_Link runs window 1
            # whatever uWindow says, P27)
            ran = sorted(ch.sender_windows())
            window = ""
            if a.window != 1 or ran != [1]:
                window = (f" window {'/'.join(map(str, ran))}"
                          + (f" (uWindow {a.window})" if ran != [a.window] else ""))
            if a.warm:
                g = sum(1 for _, _, gr in ch.warm if gr)
                line = (f"warm: records={tot.get('records', 0)} lost {tot.get('lost', 0)} "
                        f"duplicated {tot.get('duplicated', 0)} failed {failed} "
                        f"receiver_reported {tot.get('receiver_reports', 0)} restarts {k} "
                        f"(graceful {g}, kill -9 {len(ch.warm) - g}, cold {k - len(ch.warm)}) "
                        f"snapshots {rs['snapshots']}{window} seconds={wall:.0f}")
            else:
                line = (f"records={tot.get('records', 0)} lost={tot.get('lost', 0)} "
                        f"duplicated={tot.get('duplicated', 0)} failed_and_reported={failed} "
                        f"restarts={k}{window} seconds={wall:.0f}")
            if not finished:
                print(f"result: FAIL not finished within {limit:.0f} virtual seconds; {line}")
                return 1
            if tot.get("problems"):
                print(f"result: FAIL {tot['problems']} problem(s); {line}")
                return 1
            print(f"result: ok {line}")
            return 0
    except (CosimError, KeyboardInterrupt) as e:
        return result.failed(e)


if __name__ == "__main__":
    sys.exit(main())
