"""mip-kit: run one scenario file (TOML) of the test kit; exit 0 when every expectation holds,
1 otherwise (a scenario that cannot run counts as failed, with one line saying why).

    mip-kit SCENARIO.toml [--junit OUT.xml] [--results DIR] [--workdir DIR]
            [--compiler stc|matiec|auto] [--semantics matiec|openplc|iec]
            [--diagram-seconds S] [--trace-lines N]

A failure's report starts with the fault (the first record that went wrong) and the MIP
blocks' diagnosis; its sequence diagram and trace go to --results. One summary line per run
(per seed of network.seeds).

The file format is in docs/test-kit.md; paths in it are relative to the file.
"""
from __future__ import annotations

import argparse
import re
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

from stc.semantics import SEMANTICS

from .base import SEC, KitError, KitWarning
from .net import Net

# the keys a scenario may have, per table (anything else is a one-line error)
KEYS = {
    "": {"name", "network", "plc", "peer", "fault", "judge", "expect", "relay", "unicos", "scada"},
    "network": {"stations", "radio", "bitrate", "slot_gap_ms", "overhead_bytes", "loss_down",
                "loss_up", "burst", "seed", "seeds", "mode", "static_registers", "compiler",
                "semantics", "trace"},
    "plc": {"name", "sources", "config", "station", "set", "retain_period_ms", "compiler"},
    "peer": {"name", "station", "unit", "lenient", "layout", "drive", "period_ms",
             "retransmit_s", "request_s", "static_registers"},
    "fault": {"at_s", "restart", "mode", "down_s", "lose"},
    "relay": {"name", "plc", "device", "events", "rate", "burst", "base", "capacity", "overflow",
              "seq_bits", "bad_ack", "origin_ms"},
    "unicos": {"name", "plc", "device", "device_b", "marker", "little_endian_register", "down",
               "down_b"},
    "scada": {"name", "plc", "base", "poll_ms", "reack", "down"},
    "fault.lose": {"station", "direction", "record", "times"},
    "judge": {"logged", "delivered", "records"},
    "expect": {"complete_within_s", "run_s", "no_xerror", "values", "numbered_records", "step_s",
               "reached", "no_duplicates"},
    "expect.reached": {"relay", "at"},
    "expect.values": {"name", "at", "equals", "at_least", "at_most"},
}


class ScenarioError(Exception):
    pass


def _check_keys(table, where, path):
    if not isinstance(table, dict):
        raise ScenarioError(f"{path}: {where or 'the file'}: a table is expected here")
    known = KEYS[where]
    for k in table:
        if k not in known:
            at = f"{where}.{k}" if where else k
            raise ScenarioError(f"{path}: unknown key '{at}' (known in "
                                f"{'[' + where + ']' if where else 'the top level'}: "
                                f"{', '.join(sorted(known))})")


def load(path: Path):
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise ScenarioError(f"{path}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{path}: not TOML: {e}") from None
    _check_keys(doc, "", path)
    _check_keys(doc.get("network", {}), "network", path)
    for t in ("plc", "peer", "fault", "relay", "unicos", "scada"):
        items = doc.get(t, [])
        if not isinstance(items, list):
            raise ScenarioError(f"{path}: [{t}] must be an array of tables: write [[{t}]]")
        for item in items:
            _check_keys(item, t, path)
            if t == "fault" and "lose" in item:
                _check_keys(item["lose"], "fault.lose", path)
    _check_keys(doc.get("judge", {}), "judge", path)
    exp = doc.get("expect", {})
    _check_keys(exp, "expect", path)
    for v in exp.get("values", []):
        _check_keys(v, "expect.values", path)
    for v in exp.get("reached", []):
        _check_keys(v, "expect.reached", path)
    if not doc.get("plc") and not doc.get("peer"):
        raise ScenarioError(f"{path}: nothing on the network: give at least one [[plc]]")
    return doc


class Run:
    """One scenario on one Net; results are (name, message or None) pairs."""

    def __init__(self, doc, base: Path, workdir: Path, compiler=None, seed=None, semantics=None):
        self.doc, self.base, self.workdir = doc, base, workdir
        n = dict(doc.get("network", {}))
        n.pop("seeds", None)
        if seed is not None:
            n["seed"] = seed
        self.when = {}          # expectation -> virtual ns of its failure (the fault's moment)
        self.done_at = None     # virtual ns when delivered = logged
        self.delivered = None
        self.scripted = []      # [description, fired?]
        mode = n.pop("mode", "dynamic")
        if mode not in ("dynamic", "static"):
            raise ScenarioError(f"network.mode {mode!r}: dynamic or static")
        if compiler:
            n["compiler"] = compiler
        if semantics:
            n["semantics"] = semantics
        stations = n.pop("stations", 1)
        self.net = Net(workdir, stations, static=mode == "static", **n)
        self.results = []

    FORMS = ("'NAME:%MW20' (a word of PLC NAME), 'NAME:%MW20,%MW21' (two words, low and "
             "high), 'NAME:%MW20..%MW23' (a list), 'NAME:PROG.var', 'NAME:PROG.arr[0..7]' (a "
             "list), or the name of a peer, [[unicos]] or [[scada]]")

    def _named(self, name, ref, where):
        try:
            return self.net[name]
        except KitError:
            have = ", ".join(list(self.net.plcs) + list(self.net.peers)) or "none"
            raise ScenarioError(f"{where} = {ref!r}: no PLC or peer named {name!r} (have: {have}); "
                                f"a reference is {self.FORMS}") from None

    def _ref(self, ref, where="a reference"):
        """'name:ADDR', 'name:LO,HI' (two words: LO + 65536 HI) or 'name:%QW100..%QW103' (a
        located range, a list) of a PLC, or 'name' of a peer (records it accepted); returns a
        function giving the value now."""
        if not isinstance(ref, str) or not ref:
            raise ScenarioError(f"{where} = {ref!r}: a reference is {self.FORMS}")
        if ":" not in ref:
            peer = self._named(ref, ref, where)
            if hasattr(peer, "unique"):        # a control-system stand-in: what it took, once each
                return lambda: len(peer.unique())
            if not hasattr(peer, "records"):
                raise ScenarioError(f"{where} = {ref!r}: a PLC needs an address: '{ref}:%MW10'")
            return lambda: len(peer.records)
        name, addr = ref.split(":", 1)
        plc = self._named(name, ref, where)
        m = re.fullmatch(r"\s*%([IQM])([BWDL])(\d+)\s*\.\.\s*%\1\2(\d+)\s*", addr, re.I)
        if m:                          # a located range: its values as a list
            area, size, lo, hi = m.group(1).upper(), m.group(2).upper(), int(m.group(3)), int(m.group(4))
            if hi < lo or hi - lo > 1024:
                raise ScenarioError(f"{ref}: a range from low to high, at most 1025 addresses")
            names = [f"%{area}{size}{i}" for i in range(lo, hi + 1)]
            for n in names:
                plc[n]
            return lambda: [plc[n] for n in names]
        m = re.fullmatch(r"\s*([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\[(\d+)\.\.(\d+)\]\s*", addr)
        if m:                          # elements of an array variable: their values as a list
            var, lo, hi = m.group(1), int(m.group(2)), int(m.group(3))
            if hi < lo or hi - lo > 4095:
                raise ScenarioError(f"{ref}: a range from low to high, at most 4096 elements")
            names = [f"{var}[{i}]" for i in range(lo, hi + 1)]
            plc[names[0]], plc[names[-1]]
            return lambda: [plc[n] for n in names]
        if "," in addr:
            lo, hi = (a.strip() for a in addr.split(",", 1))
            plc[lo], plc[hi]          # unknown addresses fail now, one line
            return lambda: int(plc[lo]) + 65536 * int(plc[hi])
        plc[addr]
        return lambda: plc[addr]

    def setup(self):
        for p in self.doc.get("plc", []):
            for k in ("name", "sources", "config", "station"):
                if k not in p:
                    raise ScenarioError(f"[[plc]] {p.get('name', '')}: '{k}' missing")
            from mipcosim import programs as L
            srcs = []
            for s in p["sources"]:
                if s == "@st_lib":
                    srcs += L.lib_sources()
                else:
                    srcs.append(str(self.base / s))
            plc = self.net.plc(p["name"], srcs, self.base / p["config"], p["station"],
                               p.get("retain_period_ms"), p.get("compiler"))
            for addr, value in p.get("set", {}).items():
                plc[addr] = value
        for p in self.doc.get("peer", []):
            kw = {k: v for k, v in p.items() if k not in ("name", "station")}
            self.net.peer(p.get("name", "peer"), p.get("station", "mdp"), **kw)
        self._ends()
        self.faults = sorted(self.doc.get("fault", []), key=lambda f: f.get("at_s", 0))
        for f in self.faults:
            if "lose" in f:
                lo = f["lose"]
                self.net.lose(lo.get("station", 1), lo.get("direction", "up"), lo.get("record"),
                              lo.get("times", 1))
                rule, times = self.net._losses[-1], lo.get("times", 1)
                rec = "" if lo.get("record") is None else f" record {lo['record']}"
                self.scripted.append(
                    (lambda rule=rule, times=times, rec=rec, lo=lo:
                     f"lose {lo.get('direction', 'up')}{rec} at station {lo.get('station', 1)} "
                     f"fired {times - rule[3]} of {times}"))
            elif "restart" not in f:
                raise ScenarioError("a [[fault]] needs restart = \"plc\" or lose = {...}")
            elif "at_s" not in f:
                raise ScenarioError(f"[[fault]] restart {f['restart']}: at_s missing")
            else:
                kp = self.net[f["restart"]]
                mode, at = f.get("mode", "cold"), f["at_s"]
                self.scripted.append(
                    (lambda kp=kp, mode=mode, at=at:
                     f"{mode} restart of {kp.name} at {at:g} s "
                     f"{'fired' if any(m == mode and t >= at * SEC for t, m, _ in kp.restarts) else 'did not fire'}"))

    def _ends(self):
        """[[relay]], [[unicos]], [[scada]]: the chain's ends as devices of the PLCs."""
        for r in self.doc.get("relay", []):
            if "plc" not in r:
                raise ScenarioError(f"[[relay]] {r.get('name', '')}: 'plc' missing (the PLC that "
                                    "reads it)")
            kw = {k: v for k, v in r.items() if k not in ("name", "plc", "device", "events")}
            if "burst" in kw:
                b = kw["burst"]
                if not (isinstance(b, list) and len(b) == 2 and all(
                        isinstance(x, (int, float)) and x > 0 for x in b)):
                    raise ScenarioError(f"relay.burst = {b!r}: [n, every_s], both > 0")
                kw["burst"] = (int(b[0]), float(b[1]))
            events = []
            for e in r.get("events", []):
                if not (isinstance(e, list) and len(e) == 5 and isinstance(e[0], (int, float))):
                    raise ScenarioError(f"relay.events: {e!r}: [t_s, type/bit, address, "
                                        "cause/type, value]")
                events.append((e[0], e[1:]))
            self.net.relay(r.get("name", "relay"), r["plc"], r.get("device", "relay"), events, **kw)
        for u in self.doc.get("unicos", []):
            if "plc" not in u:
                raise ScenarioError(f"[[unicos]] {u.get('name', '')}: 'plc' missing (the PLC that "
                                    "writes to it)")
            kw = {k: v for k, v in u.items() if k not in ("name", "plc", "device", "device_b")}
            self.net.unicos(u.get("name", "unicos"), u["plc"], u.get("device", "unicos"),
                            u.get("device_b"), **kw)
        for c in self.doc.get("scada", []):
            if "plc" not in c:
                raise ScenarioError(f"[[scada]] {c.get('name', '')}: 'plc' missing (the PLC it "
                                    "polls)")
            kw = {k: v for k, v in c.items() if k not in ("name", "plc")}
            self.net.scada(c.get("name", "scada"), c["plc"], **kw)

    def _reached(self, exp):
        """expect.reached: every scripted event of a relay at a control-system stand-in or a
        peer (its records: 8-word entries back to back); expect.no_duplicates."""
        from .ends import KitRelay
        for v in exp.get("reached", []):
            rname, at = v.get("relay"), v.get("at")
            relay = self._named(rname, rname, "expect.reached relay") if isinstance(rname, str) \
                else None
            if not isinstance(relay, KitRelay):
                raise ScenarioError(f"expect.reached relay = {rname!r}: no [[relay]] of that name")
            if isinstance(at, str) and ":" in at:      # a PLC's log: 8-word entries back to back
                words = self._ref(at, "expect.reached at")()
                if not isinstance(words, list):
                    raise ScenarioError(f"expect.reached at = {at!r}: a range of words "
                                        "('NAME:MAIN.aLog[0..511]', 'NAME:%MW100..%MW163')")
                far = [words[:len(words) - len(words) % 8]]
            else:
                far = self._named(at, at, "expect.reached at") if isinstance(at, str) else None
                if far is None or not (hasattr(far, "unique") or hasattr(far, "records")):
                    raise ScenarioError(f"expect.reached at = {at!r}: a [[unicos]], [[scada]] or "
                                        "[[peer]] name, or a PLC's log ('NAME:MAIN.aLog[0..511]')")
                far = far if hasattr(far, "unique") else far.records
            try:
                lost = relay.missing(far)
            except KitError as e:
                lost, msg = None, f"{at}: {e}"
            else:
                msg = None if not lost else (
                    f"{len(lost)} of {len(relay.expected())} events of {rname} did not reach "
                    f"{at}; the first: {lost[0]}")
            self.results.append((f"every event of {rname} reached {at}", msg))
        for name in exp.get("no_duplicates", []):
            far = self._named(name, name, "expect.no_duplicates") if isinstance(name, str) else None
            if not hasattr(far, "duplicates"):
                raise ScenarioError(f"expect.no_duplicates: {name!r}: a [[unicos]] or [[scada]] name")
            drivers = list(far.drivers) if hasattr(far, "drivers") else [None]
            dups = [(d, e) for d in drivers for e in (far.duplicates(d) if d else far.duplicates())]
            msg = None
            if dups:
                d, e = dups[0]
                what = f"offset {e['offset']}" if "offset" in e else f"address {e['address']}"
                msg = (f"{len(dups)} duplicates at {name}; the first{' (driver ' + d + ')' if d else ''}: "
                       f"{what}, value {e['value']}, taken again at {e['t_s']:.3f} s")
            self.results.append((f"no duplicates at {name}", msg))

    def run(self):
        exp = self.doc.get("expect", {})
        judge = self.doc.get("judge", {})
        logged = self._ref(judge["logged"], "judge.logged") if "logged" in judge else None
        delivered = self._ref(judge["delivered"], "judge.delivered") if "delivered" in judge else None
        want_records = judge.get("records")
        xerrs = [(r, self._ref(r, "expect.no_xerror")) for r in exp.get("no_xerror", [])]
        within = exp.get("complete_within_s")
        step = exp.get("step_s", 0.5)
        if within is not None and (logged is None or delivered is None):
            raise ScenarioError("expect.complete_within_s needs judge.logged and judge.delivered")
        faults = [f for f in self.faults if "restart" in f]
        seen_error = {}

        def complete():
            n = logged()
            return n > 0 and delivered() == n and (want_records is None or n >= want_records)

        self.delivered = delivered

        end = int((within if within is not None else exp.get("run_s", 60)) * SEC)
        done = False
        while self.net.now < end:
            t = min(end, self.net.now + int(step * SEC))
            if faults and faults[0]["at_s"] * SEC <= t:
                f = faults.pop(0)
                self.net.run_until_time(max(self.net.now, int(f["at_s"] * SEC)))
                self.net.restart(f["restart"], f.get("mode", "cold"), f.get("down_s", 0.5))
                continue
            self.net.run_until_time(t)
            for ref, get in xerrs:
                if get() and ref not in seen_error:
                    seen_error[ref] = self.net.now
            if within is not None and complete() and not faults:
                done = True
                self.done_at = self.net.now
                break
        if within is not None:
            msg = None if done else (f"not complete within {within} s: judge logged "
                                     f"{logged()}, delivered {delivered()}")
            self.results.append((f"complete within {within} s (delivered = logged)", msg))
        for ref, _ in xerrs:
            t = seen_error.get(ref)
            self.results.append((f"no xError: {ref}", None if t is None else
                                 f"{ref} was TRUE at {t / SEC:.3f} s"))
            if t is not None:
                self.when[f"no xError: {ref}"] = t
        for v in exp.get("values", []):
            get = self._ref(v.get("at"), "expect.values at")
            got = get()
            msg = None
            if "equals" in v and got != v["equals"]:
                msg = f"{v['at']} = {got}, want {v['equals']}"
            if "at_least" in v and got < v["at_least"]:
                msg = f"{v['at']} = {got}, want at least {v['at_least']}"
            if "at_most" in v and got > v["at_most"]:
                msg = f"{v['at']} = {got}, want at most {v['at_most']}"
            self.results.append((v.get("name") or f"value {v['at']}", msg))
        nr = exp.get("numbered_records")
        if nr:
            peer = self.net[nr]
            msg = None
            for i, rec in enumerate(peer.records, 1):
                num = (rec[0] + 65536 * rec[1]) if len(rec) >= 2 else None
                if num != i:
                    msg = f"record {i}: its registers say record {num} (first words {rec[:4]})"
                    break
            self.results.append((f"numbered records at {nr}", msg))
        self._reached(exp)
        return self.results


    def summary(self):
        """One line: virtual time to completion, records, retransmissions, losses, whether the
        scripted faults fired."""
        from .report import fmt_t, observer
        net = self.net
        done = f"complete at {fmt_t(self.done_at)}" if self.done_at is not None else \
            f"not complete at {fmt_t(net.now)}" if self.delivered is not None else \
            f"ran to {fmt_t(net.now)}"          # no judge: nothing to complete
        parts = [done]
        if self.delivered is not None:
            parts.append(f"{self.delivered()} records delivered")
        retrans = 0
        obs = observer(net)
        for kp in net.plcs.values():
            for path, typ, _, _, _ in obs.blocks(kp):
                if typ != "MIP_Receiver":
                    try:
                        retrans += int(kp.plc[f"{path}.UDIRETRANSMISSIONS"])
                    except Exception:  # noqa: BLE001 - a build without the member's symbol
                        pass
        parts.append(f"{retrans} records retransmitted by the blocks")
        st = net.kernel.radio_stats()
        parts.append(f"radio lost {st['lost_down']} of {st['tel_down']} telegrams down, "
                     f"{st['lost_up']} of {st['tel_up']} up")
        if self.scripted:
            parts.append("scripted: " + ", ".join(f() for f in self.scripted))
        for e in net.ends.values():
            if hasattr(e, "report"):
                parts.append(e.report())
        return "; ".join(parts)


def seeds_of(doc, path):
    """[None] (the scenario's own seed), or the seeds of network.seeds: a list or "A..B"."""
    n = doc.get("network", {})
    if "seeds" not in n:
        return [None]
    if "seed" in n:
        raise ScenarioError(f"{path}: network: give seed or seeds, not both")
    v = n["seeds"]
    if isinstance(v, list) and v and all(isinstance(x, int) and not isinstance(x, bool) for x in v):
        return list(v)
    m = re.fullmatch(r"\s*(\d+)\s*\.\.\s*(\d+)\s*", v) if isinstance(v, str) else None
    if m and int(m.group(1)) <= int(m.group(2)):
        return list(range(int(m.group(1)), int(m.group(2)) + 1))
    raise ScenarioError(f"{path}: network.seeds = {v!r}: a list of seeds ([1, 2, 3]) or a "
                        f"range (\"1..60\")")


def junit(path: Path, name, results, seconds, props, details=None):
    suite = ET.Element("testsuite", name="mip-kit", tests=str(len(results)),
                       failures=str(sum(1 for _, m in results if m)), time=f"{seconds:.3f}")
    if props:
        pe = ET.SubElement(suite, "properties")
        for k, v in props:
            ET.SubElement(pe, "property", name=k, value=str(v))
    for case, msg in results:
        tc = ET.SubElement(suite, "testcase", classname=name, name=case)
        if msg:
            ET.SubElement(tc, "failure", message=msg).text = "\n".join(
                [msg] + list((details or {}).get(case, [])))
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(suite).write(path, encoding="utf-8", xml_declaration=True)


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(1, f"{self.prog}: error: {message} (see --help)\n")


def _clear(results: Path):
    """An earlier run's report files in results (and its seed-N folders); nothing else."""
    for d in [results] + (sorted(results.glob("seed-*")) if results.is_dir() else []):
        for pattern in ("sequence-diagram.svg", "emulator-trace-*.jsonl.gz", "modbus.pcapng.gz"):
            for f in d.glob(pattern):
                f.unlink()


def main(argv=None):
    ap = _Parser(prog="mip-kit", description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("scenario")
    ap.add_argument("--junit", help="write JUnit XML here")
    ap.add_argument("--results", help="a failure's sequence diagram and trace (default: "
                    "mip-kit-NAME next to --junit, else ./mip-kit-results)")
    ap.add_argument("--workdir", help="builds and the whole trace, kept (default: a temporary "
                    "directory, removed at the end)")
    ap.add_argument("--compiler", default=None, choices=["stc", "matiec", "auto"],
                    help="instead of the scenario's network.compiler (default stc); auto: "
                         "matiec when iec2c is on PATH")
    ap.add_argument("--semantics", default=None, choices=SEMANTICS,
                    help="stc's values where IEC 61131-3 leaves them open: matiec, openplc "
                         "(OpenPLC's matiec fork), iec (default: the scenario's "
                         "network.semantics, else PLCRT_SEMANTICS, else matiec)")
    ap.add_argument("--diagram-seconds", type=float, default=6.0,
                    help="virtual seconds a failure's sequence diagram shows, centred on the "
                         "fault (default 6)")
    ap.add_argument("--trace-lines", type=int, default=40,
                    help="lines of the readable trace around the fault (default 40)")
    ap.add_argument("--capture", type=float, default=0, metavar="SECONDS",
                    help="keep the Modbus/TCP traffic: a failure leaves SECONDS virtual "
                         "seconds of it around the fault beside the diagram as modbus.pcapng.gz, for "
                         "Wireshark with mipmb.lua (default 0: off; docs/wireshark.md)")
    a = ap.parse_args(argv)
    path = Path(a.scenario)
    name = path.stem
    results_dir = Path(a.results) if a.results else (
        Path(a.junit).parent / f"mip-kit-{name}" if a.junit else Path("mip-kit-results"))
    results_dir = results_dir.resolve()
    tmp = None
    if a.workdir:
        work = Path(a.workdir).resolve()
    else:
        import tempfile
        tmp = work = Path(tempfile.mkdtemp(prefix="mip-kit-"))
    t0 = time.perf_counter()
    results, props, details = [], [], {}
    import warnings
    catcher = warnings.catch_warnings(record=True)
    seen = catcher.__enter__()
    warnings.simplefilter("always", KitWarning)
    printed = set()

    def say_warnings():
        # stc's portability warnings and the kit's notes: each once per mip-kit run
        for w in seen:
            text = str(w.message)
            if isinstance(w.message, KitWarning) and text not in printed:
                printed.add(text)
                print(f"mip-kit: {text}")
        seen.clear()

    try:
        try:
            doc = load(path)
            name = doc.get("name", name)
            seeds = seeds_of(doc, path)
        except ScenarioError as e:
            results.append(("scenario runs", str(e)))
            print(f"FAIL scenario runs: {e}")
            seeds = []
        _clear(results_dir)
        for seed in seeds:
            sweep = len(seeds) > 1 or seed is not None
            tag = f" [seed {seed}]" if sweep else ""
            sub = f"seed-{seed}" if sweep else ""
            out = _run_one(doc, path, work / sub if sub else work, results_dir / sub if sub
                           else results_dir, a, name, seed, tag, say_warnings)
            if out is None:
                print("mip-kit: interrupted", file=sys.stderr)
                return 1
            res, pr, det = out
            results += [(c + tag, m) for c, m in res]
            props += pr
            details.update({c + tag: v for c, v in det.items()})
    finally:
        catcher.__exit__(None, None, None)
        if tmp is not None:
            import shutil
            shutil.rmtree(tmp, ignore_errors=True)
    failed = [(c, m) for c, m in results if m]
    secs = time.perf_counter() - t0
    if a.junit:
        junit(Path(a.junit), name, results, secs, props, details)
    print(f"mip-kit: {name}: {'FAILED' if failed or not results else 'passed'} "
          f"({len(results) - len(failed)}/{len(results)} expectations, {secs:.1f} s wall)")
    return 1 if failed or not results else 0


def _run_one(doc, path, work, results_dir, a, name, seed, tag, say_warnings=lambda: None):
    """One run of the scenario (one seed): prints its lines; (results, properties, report
    lines per failed expectation), or None when interrupted."""
    from .failure import failure_report
    results, props, run, ran = [], [], None, False
    head, sections = [], []
    try:
        run = Run(doc, path.resolve().parent, work, a.compiler, seed, a.semantics)
        if getattr(a, "capture", 0) > 0:          # before setup: the PLCs are wired there
            from .capture import ModbusCapture
            run.net.capture = ModbusCapture(a.capture)
        run.setup()
        ran = True
        results = run.run()
    except (ScenarioError, KitError) as e:
        results.append(("scenario runs", str(e)))
    except KeyboardInterrupt:
        return None
    failed = [(c, m) for c, m in results if m]
    if failed and ran:
        case, msg = failed[0]
        try:
            head, sections, pr = failure_report(run.net, msg, results_dir, a.diagram_seconds,
                                                t_hint=run.when.get(case),
                                                title=f"{name}{tag}", trace_lines=a.trace_lines)
            props += [(k + tag, v) for k, v in pr]
        except Exception as e:  # noqa: BLE001 - the failure itself is what matters
            head = [f"mip-kit: no report: {type(e).__name__}: {e}"]
        if run.net.capture is not None:
            from .capture import save_for_report
            title, text, prop = save_for_report(run.net, results_dir, msg,  # per seed already
                                                t_hint=run.when.get(case))
            sections.append((title, text))
            props.append((prop[0] + tag, prop[1]))
    summary = None
    if ran:
        try:
            summary = f"summary: {name}{tag}: {run.summary()}"
        except Exception as e:  # noqa: BLE001
            summary = f"summary: {name}{tag}: none ({type(e).__name__}: {e})"
    if run is not None:
        run.net.close()
    under = head
    if ("mip_fault_kind" + tag, "chain") in props and head:
        print(head[0])          # the chain's fault (the events, the hop) is the first line
        under = head[1:]
    for k, (c, m) in enumerate(failed):
        print(f"FAIL {c}{tag}: {m}")
        if k == 0:              # the fault and the blocks' diagnosis right under the first
            for line in under:
                print(line)
    for c, m in results:
        if not m:
            print(f"ok   {c}{tag}")
    for title, text in sections:
        print(f"---- {title}")
        print(text)
    say_warnings()              # after the report: the fault stays in the first lines
    if summary:
        print(summary)
    return results, props, {c: head for c, _ in failed}


if __name__ == "__main__":
    sys.exit(main())
