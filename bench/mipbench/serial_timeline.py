"""Where the time of one record goes: a transfer of the example programs (plc/outstation.st,
plc/central.st, window 1) in the co-simulation on the realistic radio, the PLCs on Modbus TCP or
RTU, and from its emulator trace the mean time of each step of a record's round trip, the
Modbus requests per record on each PLC's line and how long they keep the line busy.

    .venv/bin/python -m mipbench.serial_timeline [--link tcp|rtu:BAUD] [--status-first no|yes|N]
                                                 [--fc23] [--records N] [--payload N] [--seed S]

Defaults: --link rtu:19200, the read strategy mip-cosim uses on that link (status_first 3 on
serial lines, the whole read area over TCP), 20 records of 122 registers, seed 1. Records 5 ..
N-1 are measured (past the start-up). Deterministic: the same options print the same lines.
docs/serial.md shows and explains the output."""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import mipcosim.programs as L
import mipcosim.sim as S
from mipcosim.cli import link_timeout_ms
from mipcosim.kernel import MS
from mipcosim.trace import read_trace
from mipprobe.regmap import TRM810

STEPS = [
    ("write", "outstation: record written -> the radio answer with it starts"),
    ("air_up", "answer on air"),
    ("detect_c", "central: answer end -> the read that takes it"),
    ("read_c", "central: that read -> acknowledgement written"),
    ("wait_poll", "acknowledgement written -> the poll with it starts"),
    ("air_down", "poll on air"),
    ("detect_o", "outstation: poll end -> the read that takes it"),
    ("read_o", "outstation: that read -> next record written"),
]


def parse(argv):
    ap = argparse.ArgumentParser(prog="python -m mipbench.serial_timeline",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--link", default="rtu:19200", help="tcp or rtu:BAUD (default rtu:19200)")
    ap.add_argument("--status-first", default=None,
                    help="no, yes or the registers of the first read (default: 3 on RTU, no on TCP)")
    ap.add_argument("--fc23", action="store_true", help="device option fc23 (needs --payload <= 120)")
    ap.add_argument("--records", type=int, default=20, help="records (default 20, at least 8)")
    ap.add_argument("--payload", type=int, default=122, help="payload registers per record (default 122)")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    try:
        a.baud = L.parse_link(a.link)
    except ValueError as e:
        ap.error(str(e))
    sf = a.status_first
    if sf is None:
        a.sf = L.RTU_STATUS_FIRST if a.baud else False
    elif sf in ("no", "yes"):
        a.sf = sf == "yes"
    elif sf.isdigit() and 2 <= int(sf) < 125:
        a.sf = int(sf)
    else:
        ap.error(f"--status-first {sf}: use no, yes or a number 2..124")
    if a.records < 8:
        ap.error(f"--records {a.records}: at least 8 (records 5 .. N-1 are measured)")
    if not 1 <= a.payload <= 122 or (a.fc23 and a.payload > 120):
        ap.error(f"--payload {a.payload}: 1..122 (with --fc23 1..120)")
    return a


def rtu_chars(e):
    """RTU frame lengths (request, answer) of a trace's Modbus event"""
    fc = e["fc"]
    req = {16: 9 + 2 * e.get("wq", 0), 23: 13 + 2 * e.get("wq", 0)}.get(fc, 8)
    rsp = 5 if e["exc"] else 5 + 2 * e["rq"] if fc in (3, 4, 23) else 8
    return req, rsp


def timeline(trace):
    ev = read_trace(trace)
    mb = [e for e in ev if e["ev"] == "modbus"]
    writes = {}
    for e in mb:
        if e["ep"] == "trm" and e.get("wa") == TRM810.write_data and "w0" in e:
            writes.setdefault(e["w0"], e["t"])
    ups = {}
    for e in ev:
        if e["ev"] == "radio" and e["kind"] == "answer" and e["regs"] and not e["lost"]:
            ups.setdefault(e["r0"], (e["t0"], e["t"]))
    polls = [e for e in ev if e["ev"] == "radio" and e["kind"] == "poll" and e["regs"] and not e["lost"]]
    cen_reads = [e["t"] for e in mb if e["ep"] == "mdp" and e["fc"] in (3, 23)]
    out_reads = [e["t"] for e in mb if e["ep"] == "trm" and e["fc"] in (3, 23)]
    acks = [e for e in mb if e["ep"] == "mdp" and e.get("wa") == 10 and "w0" in e]
    first = lambda ts, t: next((x for x in ts if x >= t), None)  # noqa: E731
    rows = []
    for n in sorted(writes):
        nxt = writes.get(n + 1)
        if not 5 <= n < 65535 or n not in ups or nxt is None:
            continue
        up0, up1 = ups[n]
        cr = first(cen_reads, up1)
        aw = next((a["t"] for a in acks if a["t"] >= up1 and a["w0"] == n), None)
        p = next((p for p in polls if aw is not None and p["t0"] >= aw), None)
        orr = first(out_reads, p["t"]) if p else None
        if None in (cr, aw, p, orr):
            continue
        rows.append({"write": up0 - writes[n], "air_up": up1 - up0, "detect_c": cr - up1,
                     "read_c": aw - cr, "wait_poll": p["t0"] - aw, "air_down": p["t"] - p["t0"],
                     "detect_o": orr - p["t"], "read_o": nxt - orr, "cycle": nxt - writes[n],
                     "t0": writes[n], "t1": nxt})
    return ev, rows


def main(argv=None):
    a = parse(sys.argv[1:] if argv is None else argv)
    s = S.Setup(stations=1, records=a.records, payload=a.payload, seed=a.seed,
                radio=S.Radio.realistic(), link_baud=a.baud,
                timeout_ms=3000 + link_timeout_ms(a.baud), status_first=a.sf, fc23=a.fc23)
    with tempfile.TemporaryDirectory(prefix="serial-timeline-") as tmp:
        trace = Path(tmp) / "trace.jsonl"
        with S.LoggerLink(s, Path(tmp), trace=trace) as ch:
            if not ch.run_to_end(a.records * 60 * S.SEC, step_ns=100 * MS, settle_ns=0):
                print(f"mipbench.serial_timeline: error: {a.records} records not read out after "
                      f"{ch.now // S.SEC} virtual s", file=sys.stderr)
                return 1
        ev, rows = timeline(trace)
    if not rows:
        print("mipbench.serial_timeline: error: no record to measure", file=sys.stderr)
        return 1
    sf = {False: "no", True: "yes"}.get(a.sf, a.sf)
    print(f"{a.link}, status_first {sf}{', fc23' if a.fc23 else ''}: {a.records} records of "
          f"{a.payload} registers, window 1, realistic radio, seed {a.seed}; records "
          f"{len(rows)} measured, mean ms per record:")
    mean = lambda k: statistics.mean(r[k] for r in rows) / MS  # noqa: E731
    for key, what in STEPS:
        print(f"  {what:<62} {mean(key):6.1f}")
    print(f"  {'cycle (= the sum)':<62} {mean('cycle'):6.1f}")
    t0, t1, n = rows[0]["t0"], rows[-1]["t1"], len(rows)
    slots = sum(1 for e in ev if e["ev"] == "radio" and e["kind"] == "poll" and t0 <= e["t"] < t1)
    print(f"  radio: {slots / n:.2f} slots per record")
    char = 11 / a.baud * 1000 if a.baud else 0
    gap = (1.75 if a.baud > 19200 else 3.5 * char) if a.baud else 0
    for ep, who in (("trm", "outstation"), ("mdp", "central")):
        q = [e for e in ev if e["ev"] == "modbus" and e["ep"] == ep and t0 <= e["t"] < t1]
        kinds = {}
        for e in q:
            k = f"fc{e['fc']}" + (f" r{e['rq']}" if "rq" in e else "") + (f" w{e['wq']}" if "wq" in e else "")
            kinds[k] = kinds.get(k, 0) + 1
        busy = sum(sum(rtu_chars(e)) * char + 2 * gap for e in q) / n
        print(f"  {who}: {len(q) / n:.1f} requests per record ("
              + ", ".join(f"{k} {v / n:.2f}" for k, v in sorted(kinds.items())) + ")"
              + (f", line busy {busy:.0f} ms" if a.baud else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
