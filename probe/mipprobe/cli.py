"""mip-probe: the commissioning checklist of docs/commissioning.md, run per station against the
real modems (or the emulator), the radio's round trips and the blocks' parameters from them.

    mip-probe --mdp 192.168.1.10 --trm 1=192.168.1.21 --trm 2=192.168.1.22 --report site.json

Exit status: 0 every station ok, 1 a station failed, 2 bad arguments, 130 interrupted (Ctrl-C:
what was measured is written all the same)."""
from __future__ import annotations

import argparse
import datetime
import sys
import time

from . import __version__
from .link import Endpoint, SpecError, Tracer, close_serial, parse_spec
from .report import junit, measured, params_lines, report_json, station_lines
from .sizing import plcrt_master, recommend, st_snippet
from .station import Options, StationProbe


class Parser(argparse.ArgumentParser):
    def error(self, message):          # one line, no usage block
        sys.stderr.write(f"mip-probe: error: {message} (mip-probe --help)\n")
        raise SystemExit(2)


def parse(argv):
    p = Parser(prog="mip-probe", description=__doc__.split("\n\n")[0],
               formatter_class=argparse.RawDescriptionHelpFormatter,
               epilog="Endpoints: HOST[:PORT] (Modbus TCP, port 502) or "
                      "rtu:DEVICE[:BAUD[:FRAME]] (Modbus RTU, 19200 8E1), either with @UNIT "
                      "(a TRM's unit id, 1 by default; the MDP's is the station). Stop the "
                      "PLCs first: the probe writes test blocks where the checklist does. "
                      "docs/commissioning.md explains every line.")
    p.add_argument("--mdp", required=True, metavar="ENDPOINT", help="the MDP-810 (central)")
    p.add_argument("--trm", action="append", required=True, metavar="S=ENDPOINT",
                   help="the TRM-810 of station S (repeat for every station)")
    p.add_argument("--blocks", type=int, default=10, metavar="N",
                   help="round trips measured per station and direction (default 10; 0: none)")
    p.add_argument("--registers", type=int, default=123, metavar="N",
                   help="length of the measured blocks in dynamic mode: the records' (default 123)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="a test block must arrive and be confirmed within S s (default 10)")
    p.add_argument("--watch", type=float, default=2.0, metavar="S",
                   help="watch S s for a PLC writing before writing anything (default 2)")
    p.add_argument("--request-timeout", type=float, default=1.0, metavar="S",
                   help="a modem must answer one Modbus request within S s (default 1)")
    p.add_argument("--poll-ms", type=float, default=10.0, metavar="MS",
                   help="time between the reads that wait for a block (default 10)")
    p.add_argument("--force", action="store_true", help="probe although a PLC writes")
    p.add_argument("--report", metavar="FILE", help="the JSON report")
    p.add_argument("--trace", metavar="FILE",
                   help="the trace (JSON lines, the emulator's format: mip-view --follow FILE)")
    p.add_argument("--junit", metavar="FILE", help="JUnit XML: one test case per station and check")
    p.add_argument("--st", metavar="FILE", help="the recommended parameters as ST constants")
    p.add_argument("--plcrt", metavar="FILE",
                   help="the recommended read period and reply timeout as a plcrt [master] section")
    p.add_argument("--version", action="version", version=f"mip-probe {__version__}")
    a = p.parse_args(argv)
    try:
        a.mdp_spec = parse_spec(a.mdp, None)
        a.stations = {}
        for t in a.trm:
            s, sep, spec = t.partition("=")
            if not sep or not s.isdigit() or not 1 <= int(s) <= 247:
                raise SpecError(f"--trm {t}: S=ENDPOINT with a station 1..247")
            if int(s) in a.stations:
                raise SpecError(f"--trm {t}: station {s} given twice")
            a.stations[int(s)] = parse_spec(spec, 1)
    except SpecError as e:
        p.error(str(e))
    for name, v, lo in (("--blocks", a.blocks, 0), ("--registers", a.registers, 8),
                        ("--timeout", a.timeout, 0.01), ("--watch", a.watch, 0),
                        ("--request-timeout", a.request_timeout, 0.01), ("--poll-ms", a.poll_ms, 0)):
        if v < lo:
            p.error(f"{name} {v:g}: at least {lo:g}")
    if a.registers > 123:
        p.error(f"--registers {a.registers}: at most 123 (one FC16, note §1.1.2)")
    return a


def main(argv=None):
    a = parse(argv)
    opts = Options(timeout=a.timeout, watch=a.watch, poll=a.poll_ms / 1000, blocks=a.blocks,
                   registers=a.registers, force=a.force)
    try:
        tracer = Tracer(a.trace)
    except OSError as e:
        sys.stderr.write(f"mip-probe: error: {a.trace}: {e.strerror}\n")
        return 2
    start = time.monotonic()
    eps = {s: (Endpoint(a.mdp_spec, "mdp", s, s, tracer, a.request_timeout),
               Endpoint(spec, "trm", s, spec["unit"], tracer, a.request_timeout))
           for s, spec in sorted(a.stations.items())}
    results, interrupted = [], False
    try:
        for k, (s, (mdp, trm)) in enumerate(eps.items(), 1):
            sys.stderr.write(f"mip-probe: station {s} ({k} of {len(eps)}): TRM {trm.text}, MDP "
                             f"{mdp.text} unit {s} ...\n")
            sys.stderr.flush()
            others = [(s2, e[1]) for s2, e in eps.items() if s2 != s]
            probe = StationProbe(s, mdp, trm, opts, others)
            t0 = time.monotonic()
            try:
                results.append(probe.run())
            except KeyboardInterrupt:
                results.append(probe.r)
                raise
            for line in station_lines(results[-1]):
                print(line)
            sys.stdout.flush()
            sys.stderr.write(f"mip-probe: station {s} done in {time.monotonic() - t0:.1f} s\n")
            sys.stderr.flush()
    except KeyboardInterrupt:
        interrupted = True
        for line in station_lines(results[-1]) if results and results[-1].interrupted else []:
            print(line)
    finally:
        for mdp, trm in eps.values():
            mdp.close()
            trm.close()
        close_serial()
    params = None
    down, up = measured(results)
    if down and up:
        answers = [x for mdp, trm in eps.values() for x in mdp.latencies + trm.latencies]
        rtu = [sp for sp in [a.mdp_spec] + list(a.stations.values()) if sp["kind"] == "rtu"]
        slow = min(rtu, key=lambda sp: sp["baud"]) if rtu else None
        params = recommend(down, up, answers, baud=slow["baud"] if slow else None,
                           frame=slow["frame"] if slow else "8E1", registers=a.registers)
        for line in params_lines(params):
            print(line)
    seconds = time.monotonic() - start
    failed = [r for r in results if r.verdict() is not None]
    meta = {"tool": "mip-probe", "version": __version__,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "argv": list(sys.argv[1:] if argv is None else argv), "seconds": round(seconds, 1),
            "interrupted": interrupted, "stations_given": sorted(a.stations)}
    tracer.line(ev="probe", check="end", ok=not failed and not interrupted,
                text=f"{len(results)} of {len(eps)} stations probed")
    tracer.close()
    written = []
    try:
        if a.report:
            report_json(a.report, results, params, meta)
            written.append(a.report)
        if a.junit:
            junit(a.junit, results, seconds)
            written.append(a.junit)
        if a.st and params:
            with open(a.st, "w", encoding="utf-8") as f:
                f.write(st_snippet(params, f"mip-probe {meta['date']}: stations "
                                           f"{', '.join(str(r.station) for r in results)}"))
            written.append(a.st)
        if a.plcrt and params:
            with open(a.plcrt, "w", encoding="utf-8") as f:
                f.write(plcrt_master(params, f"mip-probe {meta['date']}"))
            written.append(a.plcrt)
    except OSError as e:
        sys.stderr.write(f"mip-probe: error: {e.filename}: {e.strerror}\n")
        return 2
    if a.trace:
        written.append(a.trace)
    where = f"; wrote {', '.join(written)}" if written else ""
    if interrupted:
        print(f"result: INTERRUPTED after {len(results)} of {len(eps)} stations{where}")
        return 130
    if failed:
        print(f"result: FAIL {len(failed)} of {len(eps)} stations: "
              + ", ".join(f"station {r.station} ({r.verdict().name})" for r in failed) + where)
        return 1
    print(f"result: ok {len(eps)} station{'s' if len(eps) > 1 else ''}{where}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
