"""What the probe leaves: the lines it prints, the JSON report, the JUnit XML, the ST constants."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

from .sizing import stats_ms
from .station import CHECKS


def station_lines(r):
    """The station's lines: the first says ok, or the first failing check and what to change."""
    bad = r.verdict()
    if r.interrupted:
        head = f"station {r.station}: INTERRUPTED (Ctrl-C) during the checks"
    elif bad is not None:
        head = f"station {r.station}: FAIL {bad.name}: {bad.text}"
    else:
        head = f"station {r.station}: ok: every check passed"
    out = [head]
    for name in CHECKS + ["round trips"]:
        c = r.checks.get(name)
        tag = "-" if c is None or c.ok is None else ("ok" if c.ok else "FAIL")
        out.append(f"  {tag:<5}{name:<14}{c.text if c else 'not run'}")
    return out


def measured(results):
    """every station's delivery times (s) and the modems' answer times, for the sizing"""
    down, up = [], []
    for r in results:
        if r.measure:
            down += r.measure["down"]["delivered_s"]
            up += r.measure["up"]["delivered_s"]
    return down, up


def params_lines(p):
    return (["recommended (docs/commissioning.md, \"What the probe recommends\"):"]
            + [f"  {k:<20}{p[k]:>8}  {p['why'][k]}" for k in p["why"]])


def report_json(path, results, params, meta):
    doc = dict(meta)
    doc["stations"] = []
    for r in results:
        m = None
        if r.measure:
            m = {"registers": r.measure["registers"], "blocks": r.measure["blocks"]}
            for d in ("down", "up"):
                x = r.measure[d]
                m[d] = {"delivered_ms": stats_ms(x["delivered_s"]),
                        "confirmed_ms": stats_ms(x["confirmed_s"]),
                        "repeated": x["duplicates"], "lost": x["lost"], "damaged": x["damaged"],
                        "slots": x["slots"],
                        "samples_ms": [round(t * 1000, 2) for t in x["delivered_s"]]}
        bad = r.verdict()
        doc["stations"].append({
            "station": r.station, "trm": r.trm, "mdp": r.mdp,
            "result": "interrupted" if r.interrupted else ("fail" if bad else "ok"),
            "first_failure": f"{bad.name}: {bad.text}" if bad else None,
            "checks": [{"check": c, "ok": r.checks[c].ok, "text": r.checks[c].text}
                       for c in CHECKS + ["round trips"] if c in r.checks],
            "round_trips": m})
    doc["recommended"] = params
    with open(path, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


def junit(path, results, seconds):
    cases = []
    for r in results:
        for name in CHECKS + ["round trips"]:
            c = r.checks.get(name)
            tc = ET.Element("testcase", classname=f"mip-probe.station{r.station}", name=name)
            if c is None or c.ok is None:
                ET.SubElement(tc, "skipped", message=c.text if c is not None else
                              "interrupted" if r.interrupted else "not run: an earlier check failed")
            elif not c.ok:
                ET.SubElement(tc, "failure", message=c.text)
            cases.append(tc)
    suite = ET.Element("testsuite", name="mip-probe", tests=str(len(cases)),
                       failures=str(sum(tc.find("failure") is not None for tc in cases)),
                       skipped=str(sum(tc.find("skipped") is not None for tc in cases)),
                       time=f"{seconds:.3f}")
    suite.extend(cases)
    ET.ElementTree(suite).write(path, encoding="utf-8", xml_declaration=True)
