"""mip-cosim run|soak --chain: the whole chain of issue 35 in the co-simulation, virtual time.

relay -> outstation PLC -> radio -> central PLC -> SCADA (mipcosim.chain).

    mip-cosim run --chain [--events 300] [--loss 0.3] [--restart-every S] ...
    mip-cosim soak --chain            # 10^5 events, 30 % loss, warm restarts, SCADA outages
    mip-cosim soak --chain --cold     # the central restarts cold: lost 0, duplicates counted

Ends with `result: ok events=N ...` (exit 0) or `result: FAIL <what differs>` (exit 1).
"""
from __future__ import annotations

import argparse
import random
import tempfile
import time
from pathlib import Path

from . import chain as C
from .chain import ChainSetup, SoeChain, SoeParams, check_chain, script
from . import result
from .sim import MS, SEC, CosimError, Radio


def parse(argv):
    p = argparse.ArgumentParser(prog="mip-cosim --chain", description=__doc__.splitlines()[0])
    p.add_argument("what", choices=["run", "soak"])
    p.add_argument("--chain", action="store_true", help="(this mode)")
    p.add_argument("--events", type=int, help="relay events (run: 300, soak: 100000)")
    p.add_argument("--every-ms", type=float, default=50.0,
                   help="ms between two relay events (default 50: 20 events/s)")
    p.add_argument("--loss", type=float, help="telegram loss per direction (run: 0.1, soak: 0.3)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--per-record", type=int, default=15, help="relay entries per MIP record (1..15)")
    p.add_argument("--per-transfer", type=int, default=8,
                   help="records per transfer at most (default 8: half the logger's ring)")
    p.add_argument("--handover", choices=["pull", "push"], default="pull",
                   help="the central's hand-over to the control system: pull (MIP_SoeServer, a "
                        "polling SCADA; default) or push (MIP_UnicosEvents to WinCC OA's "
                        "redundant pair of UNICOS drivers)")
    p.add_argument("--scada-ms", type=int, default=50, help="the SCADA's polling interval in ms")
    p.add_argument("--realistic", action="store_true", help="9600 bit/s, 20 ms gaps")
    p.add_argument("--restart-every", type=float,
                   help="virtual seconds between faults, in turn: a warm restart of the "
                        "outstation, of the central (kill -9, every third graceful), a control-"
                        "system outage (the SCADA, or the active UNICOS driver), with "
                        "--handover push a fail-over of the driver pair, a restart of the relay "
                        "(its recorder emptied; what it held is its own loss, counted apart) "
                        "(run: none, soak: 30)")
    p.add_argument("--no-relay-restarts", action="store_true",
                   help="leave the relay out of the faults")
    p.add_argument("--cold", action="store_true",
                   help="the central restarts cold (nothing retained): lost 0 is demanded, "
                        "duplicates are counted; the outstation stays warm (its logger holds "
                        "entries the relay deleted: a cold one loses them)")
    p.add_argument("--ack-on-receipt", action="store_true",
                   help="the central acknowledges a record over the radio once its entries are "
                        "queued in MIP_SoeServer, not after the SCADA took them: for a "
                        "measurement; a central restart can then lose entries")
    p.add_argument("--limit", type=float, default=0, help="virtual seconds before giving up")
    p.add_argument("--trace", help="emulator trace (JSON lines) to this file")
    p.add_argument("--workdir", help="build and scratch directory (default: a temp dir)")
    a = p.parse_args(argv)
    soak = a.what == "soak"
    a.events = a.events if a.events is not None else (100_000 if soak else 300)
    a.loss = a.loss if a.loss is not None else (0.3 if soak else 0.1)
    a.restart_every = a.restart_every if a.restart_every is not None else (30 if soak else 0)
    if a.events < 1:
        p.error("--events must be at least 1")
    if not 0 <= a.loss < 1:
        p.error("--loss must be in 0..1 (exclusive)")
    if not 1 <= a.per_record <= 15:
        p.error("--per-record must be in 1..15 (8 registers an entry, 122 in a record)")
    if not 1 <= a.per_transfer <= 65534:
        p.error("--per-transfer must be in 1..65534")
    if not 1 <= a.scada_ms <= 60000:
        p.error("--scada-ms must be in 1..60000")
    if a.every_ms <= 0:
        p.error("--every-ms must be positive")
    return a


def main(argv=None):
    a = parse(argv)
    events = script(a.events, every_s=a.every_ms / 1000, seed=a.seed)
    st = ChainSetup(events=events, loss=a.loss, seed=a.seed,
                    radio=Radio.realistic() if a.realistic else Radio(),
                    params=SoeParams(per_record=a.per_record, per_transfer=a.per_transfer,
                                     retain=True,
                                     ack_on_receipt=a.ack_on_receipt,
                                     redundant=a.handover == "push",
                                     timeout_ms=3000 if a.realistic else 300),
                    scada_period_ms=a.scada_ms, handover=a.handover)
    workdir = Path(a.workdir or tempfile.mkdtemp(prefix="mipcosim-chain-"))
    last_event_s = events[-1][0]
    limit = a.limit or (60 + last_event_s * 2 / (1 - a.loss) ** 2)
    rnd = random.Random(a.seed)
    t0 = time.monotonic()
    try:
        with SoeChain(st, workdir, trace=a.trace) as ch:
            faults = (f", a fault every {a.restart_every:g} s ({'central cold' if a.cold else 'warm'}"
                      f" restarts, {'driver outages and fail-overs' if a.handover == 'push' else 'SCADA outages'}"
                      f"{'' if a.no_relay_restarts else ', relay restarts'})"
                      if a.restart_every else "")
            print(f"mip-cosim: {a.what} --chain: {a.events} relay events every {a.every_ms:g} ms, "
                  f"{a.per_record} per record, loss {a.loss:.0%}, seed {a.seed}, "
                  + ("pushed to a redundant pair of UNICOS drivers" if a.handover == "push" else
                     f"SCADA polls every {a.scada_ms} ms") + faults, flush=True)
            k = 0
            next_fault = a.restart_every * SEC if a.restart_every else None
            last_report = time.monotonic()
            finished = False
            quiet = 0        # seconds with nothing left on the way (settled: the rest is lost)
            while ch.now < limit * SEC:
                ch.run_for(SEC)
                if next_fault is not None and ch.now >= next_fault and not ch.finished():
                    cycle = (4 if a.handover == "push" else 3) + (0 if a.no_relay_restarts else 1)
                    step = k % cycle
                    if step == cycle - 1 and not a.no_relay_restarts:
                        ch.restart_relay()
                    elif step == 2:
                        if a.handover == "push":
                            ch.driver_outage(rnd.randint(1, 5) * SEC)
                        else:
                            ch.scada_outage(rnd.randint(1, 5) * SEC)
                    elif step == 3:
                        ch.failover()
                    else:
                        who = "out" if step == 0 else "cen"
                        kind = "graceful" if (k // cycle) % 3 == 2 else "warm"
                        if a.cold and who == "cen":
                            kind = "cold"
                        ch.restart(who, kind, down_ns=rnd.randint(100, 2000) * MS)
                    k += 1
                    next_fault += a.restart_every * SEC
                if time.monotonic() - last_report > 10:
                    print(f"  t={ch.now / SEC:.0f}s virtual, {time.monotonic() - t0:.0f}s wall: "
                          f"{len(ch.distinct)}/{a.events} events at the control system, {k} faults", flush=True)
                    last_report = time.monotonic()
                if ch.finished():
                    ch.run_for(2 * SEC)
                    finished = True
                    break
                quiet = quiet + 1 if ch.settled() else 0
                if quiet >= 5:
                    break
            rep = check_chain(ch)
            radio = ch.radio_stats()
            wall = time.monotonic() - t0
            kinds = [kd for _, who, kd in ch.restarts if who != "relay"]
            relay_restarts = len(ch.restarts) - len(kinds)
            for p in rep.problems[:10]:
                print(f"  problem: {p}")
            print(f"  radio: telegrams={radio['tel_up'] + radio['tel_down']} "
                  f"lost={radio['lost_up'] + radio['lost_down']}; relay: acknowledged="
                  f"{ch.relay_stats()['acknowledged']} refused_acks={ch.relay_stats()['bad_acks']} "
                  f"restarts={relay_restarts} (events it held then, not yet stored at the outstation: "
                  f"{len(ch.at_risk)}, of them never at the control system: {rep.lost_at_relay}); "
                  + (f"drivers: events A={len(ch.drivers['a'].events)} B={len(ch.drivers['b'].events)}, "
                     f"marked duplicates A={ch.drivers['a'].duplicates} B={ch.drivers['b'].duplicates}; "
                     if ch.push else f"SCADA: failed_polls={ch.scada_failures}; ")
                  + f"{ch.now / SEC:.0f} s virtual")
            # transfers that failed (the outstation sends them again; the central drops them):
            # the retained counters, over warm restarts; a cold central starts its own at 0
            failed = ch.mw("out", C.OUT_FAILED) + ch.mw("cen", C.PUSH_FAILED if ch.push else C.CEN_FAILED)
            explained = a.cold or a.handover == "push"
            cold = (f" (after a central restart: {rep.restart_duplicates})" if explained else "")
            line = (f"events={rep.events} lost {rep.lost} duplicated {rep.duplicated}{cold} "
                    f"failed {failed} changed {rep.changed} out_of_order {rep.out_of_order} "
                    f"restarts {len(kinds)} (graceful {kinds.count('graceful')}, kill -9 "
                    f"{kinds.count('warm')}, cold {kinds.count('cold')}) "
                    f"relay_restarts {relay_restarts} (its own loss {rep.lost_at_relay}) "
                    f"{'driver_outages' if a.handover == 'push' else 'scada_outages'} "
                    f"{ch.scada_outages}{f' failovers {ch.failovers}' if a.handover == 'push' else ''} snapshots {ch.snapshots()} seconds={wall:.0f}")
            if not finished and not quiet:
                print(f"result: FAIL not finished within {limit:.0f} virtual seconds; {line}")
                return 1
            bad = rep.lost or (failed and not a.cold) or rep.changed or rep.out_of_order or rep.relay_left or rep.relay_dropped
            if bad or rep.duplicated > (rep.restart_duplicates if explained else 0):
                print(f"result: FAIL {rep.problems[0] if rep.problems else 'see above'}; {line}")
                return 1
            print(f"result: ok {line}")
            return 0
    except (CosimError, KeyboardInterrupt) as e:
        return result.failed(e)
