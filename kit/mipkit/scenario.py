"""mip-kit: run one scenario file (TOML) of the test kit; exit 0 when every expectation holds,
1 otherwise (a scenario that cannot run counts as failed, with one line saying why).

    mip-kit SCENARIO.toml [--junit OUT.xml] [--workdir DIR] [--compiler stc|matiec|auto]

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

from .net import SEC, KitError, Net

# the keys a scenario may have, per table (anything else is a one-line error)
KEYS = {
    "": {"name", "network", "plc", "peer", "fault", "judge", "expect"},
    "network": {"stations", "radio", "bitrate", "slot_gap_ms", "overhead_bytes", "loss_down",
                "loss_up", "burst", "seed", "mode", "static_registers", "compiler", "trace"},
    "plc": {"name", "sources", "config", "station", "set", "retain_period_ms", "compiler"},
    "peer": {"name", "station", "unit", "lenient", "layout", "drive", "period_ms",
             "retransmit_s", "request_s", "static_registers"},
    "fault": {"at_s", "restart", "mode", "down_s", "lose"},
    "fault.lose": {"station", "direction", "record", "times"},
    "judge": {"logged", "delivered", "records"},
    "expect": {"complete_within_s", "run_s", "no_xerror", "values", "numbered_records", "step_s"},
    "expect.values": {"at", "equals", "at_least", "at_most"},
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
    for t in ("plc", "peer", "fault"):
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
    if not doc.get("plc") and not doc.get("peer"):
        raise ScenarioError(f"{path}: nothing on the network: give at least one [[plc]]")
    return doc


class Run:
    """One scenario on one Net; results are (name, message or None) pairs."""

    def __init__(self, doc, base: Path, workdir: Path, compiler=None):
        self.doc, self.base, self.workdir = doc, base, workdir
        n = dict(doc.get("network", {}))
        mode = n.pop("mode", "dynamic")
        if mode not in ("dynamic", "static"):
            raise ScenarioError(f"network.mode {mode!r}: dynamic or static")
        if compiler:
            n["compiler"] = compiler
        stations = n.pop("stations", 1)
        self.net = Net(workdir, stations, static=mode == "static", **n)
        self.results = []

    def _ref(self, ref):
        """'name:ADDR', 'name:LO,HI' (two words: LO + 65536 HI) or 'name:%QW100..%QW103' (a
        located range, a list) of a PLC, or 'name' of a peer (records it accepted); returns a
        function giving the value now."""
        if not isinstance(ref, str) or not ref:
            raise ScenarioError(f"{ref!r}: a reference is 'plc:%MW10', 'plc:%MW10,%MW11', "
                                "'plc:PROG.var' or a peer's name")
        if ":" not in ref:
            peer = self.net[ref]
            if not hasattr(peer, "records"):
                raise ScenarioError(f"{ref}: a PLC needs an address: '{ref}:%MW10'")
            return lambda: len(peer.records)
        name, addr = ref.split(":", 1)
        plc = self.net[name]
        m = re.fullmatch(r"\s*%([IQM])([BWDL])(\d+)\s*\.\.\s*%\1\2(\d+)\s*", addr, re.I)
        if m:                          # a located range: its values as a list
            area, size, lo, hi = m.group(1).upper(), m.group(2).upper(), int(m.group(3)), int(m.group(4))
            if hi < lo or hi - lo > 1024:
                raise ScenarioError(f"{ref}: a range from low to high, at most 1025 addresses")
            names = [f"%{area}{size}{i}" for i in range(lo, hi + 1)]
            for n in names:
                plc[n]
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
            from mipcosim import layout as L
            srcs = []
            for s in p["sources"]:
                if s == "@st_lib":
                    srcs += [str(L.ST_LIB / f) for f in L.LIB_FILES]
                else:
                    srcs.append(str(self.base / s))
            plc = self.net.plc(p["name"], srcs, self.base / p["config"], p["station"],
                               p.get("retain_period_ms", 1000), p.get("compiler"))
            for addr, value in p.get("set", {}).items():
                plc[addr] = value
        for p in self.doc.get("peer", []):
            kw = {k: v for k, v in p.items() if k not in ("name", "station")}
            self.net.peer(p.get("name", "peer"), p.get("station", "mdp"), **kw)
        self.faults = sorted(self.doc.get("fault", []), key=lambda f: f.get("at_s", 0))
        for f in self.faults:
            if "lose" in f:
                lo = f["lose"]
                self.net.lose(lo.get("station", 1), lo.get("direction", "up"), lo.get("record"),
                              lo.get("times", 1))
            elif "restart" not in f:
                raise ScenarioError("a [[fault]] needs restart = \"plc\" or lose = {...}")
            elif "at_s" not in f:
                raise ScenarioError(f"[[fault]] restart {f['restart']}: at_s missing")
            else:
                self.net[f["restart"]]

    def run(self):
        exp = self.doc.get("expect", {})
        judge = self.doc.get("judge", {})
        logged = self._ref(judge["logged"]) if "logged" in judge else None
        delivered = self._ref(judge["delivered"]) if "delivered" in judge else None
        want_records = judge.get("records")
        xerrs = [(r, self._ref(r)) for r in exp.get("no_xerror", [])]
        within = exp.get("complete_within_s")
        step = exp.get("step_s", 0.5)
        if within is not None and (logged is None or delivered is None):
            raise ScenarioError("expect.complete_within_s needs judge.logged and judge.delivered")
        faults = [f for f in self.faults if "restart" in f]
        seen_error = {}

        def complete():
            n = logged()
            return n > 0 and delivered() == n and (want_records is None or n >= want_records)

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
                break
        if within is not None:
            msg = None if done else (f"not complete within {within} s: judge logged "
                                     f"{logged()}, delivered {delivered()}")
            self.results.append((f"complete within {within} s (delivered = logged)", msg))
        for ref, _ in xerrs:
            t = seen_error.get(ref)
            self.results.append((f"no xError: {ref}", None if t is None else
                                 f"{ref} was TRUE at {t / SEC:.3f} s"))
        for v in exp.get("values", []):
            get = self._ref(v.get("at"))
            got = get()
            msg = None
            if "equals" in v and got != v["equals"]:
                msg = f"{v['at']} = {got}, want {v['equals']}"
            if "at_least" in v and got < v["at_least"]:
                msg = f"{v['at']} = {got}, want at least {v['at_least']}"
            if "at_most" in v and got > v["at_most"]:
                msg = f"{v['at']} = {got}, want at most {v['at_most']}"
            self.results.append((f"value {v['at']}", msg))
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
        return self.results


def junit(path: Path, name, results, seconds, props):
    suite = ET.Element("testsuite", name="mip-kit", tests=str(len(results)),
                       failures=str(sum(1 for _, m in results if m)), time=f"{seconds:.3f}")
    if props:
        pe = ET.SubElement(suite, "properties")
        for k, v in props:
            ET.SubElement(pe, "property", name=k, value=str(v))
    for case, msg in results:
        tc = ET.SubElement(suite, "testcase", classname=name, name=case)
        if msg:
            ET.SubElement(tc, "failure", message=msg).text = msg
    ET.ElementTree(suite).write(path, encoding="utf-8", xml_declaration=True)


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(1, f"{self.prog}: error: {message} (see --help)\n")


def main(argv=None):
    ap = _Parser(prog="mip-kit", description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("scenario")
    ap.add_argument("--junit", help="write JUnit XML here")
    ap.add_argument("--workdir", help="builds, trace and diagram (default: next to --junit, "
                    "else ./mip-kit-work)")
    ap.add_argument("--compiler", default=None, choices=["stc", "matiec", "auto"],
                    help="instead of the scenario's network.compiler (default stc); auto: "
                         "matiec when iec2c is on PATH")
    a = ap.parse_args(argv)
    path = Path(a.scenario)
    name = path.stem
    work = Path(a.workdir) if a.workdir else (Path(a.junit).parent / f"mip-kit-{name}" if a.junit
                                               else Path("mip-kit-work"))
    work = work.resolve()
    t0 = time.perf_counter()
    results, props, run, ran = [], [], None, False
    try:
        doc = load(path)
        name = doc.get("name", name)
        run = Run(doc, path.resolve().parent, work, a.compiler)
        run.setup()
        ran = True
        results = run.run()
    except (ScenarioError, KitError) as e:
        results.append(("scenario runs", str(e)))
    except KeyboardInterrupt:
        print("mip-kit: interrupted", file=sys.stderr)
        return 1
    failed = [(c, m) for c, m in results if m]
    if failed and ran and run.net.trace_path is not None:
        try:
            run.net.flush_trace()
            svg = run.net.diagram(work / "sequence-diagram.svg", title=f"{name}: the last records")
            if svg:
                props += [("mip_diagram", svg), ("mip_trace", run.net.trace_path)]
        except Exception as e:  # noqa: BLE001 - the failure itself is what matters
            props.append(("mip_diagram", f"none: {e}"))
    if run is not None:
        run.net.close()
    secs = time.perf_counter() - t0
    for c, m in results:
        print(f"{'FAIL' if m else 'ok  '} {c}" + (f": {m}" if m else ""))
    for k, v in props:
        print(f"     {k}: {v}")
    if a.junit:
        junit(Path(a.junit), name, results, secs, props)
    print(f"mip-kit: {name}: {'FAILED' if failed or not results else 'passed'} "
          f"({len(results) - len(failed)}/{len(results)} expectations, {secs:.1f} s wall)")
    return 1 if failed or not results else 0


if __name__ == "__main__":
    sys.exit(main())
