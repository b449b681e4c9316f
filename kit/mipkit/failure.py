"""The whole failure report of a failed test or scenario (docs/test-kit.md, "When a test
fails"): the fault of a chain (chainreport) or of a transfer (report), the blocks at the fault
and at the end, the diagram and the trace around it. Apart from report.py so that chainreport
can use report's readers without a cycle (issue 45)."""
from __future__ import annotations

import gzip
import re
from pathlib import Path

from .base import SEC
from .chainreport import chain_fault
from .report import (TRACE_KEEP_S, Fault, _window_lines, diagnosis_lines, enum_name, find_fault,
                     fmt_t, observer, trace_summary)


def failure_report(net, message, outdir: Path, window_s=6.0, t_hint=None, title="the fault",
                   trace_lines=40):
    """(first lines, [(section title, text)], [(property, value)]) for a failed test or
    scenario on `net`; writes the diagram and the trace around the fault into outdir."""
    chain = chain_fault(net)
    if chain is not None:
        # a chain (relay to control system): the events and the hop where they stopped, from
        # what each hop saw; no record of the radio's numbering is the fault here
        fault = Fault(None, chain.t, chain.line, chain.station)
        head = [f"mip-kit: fault: {fault.text}"]
    else:
        fault = find_fault(net, message, t_hint)
        head = [f"mip-kit: fault: {fault.text}",
                f"mip-kit: the blocks at the fault ({fmt_t(fault.t)}):"]
        at_fault = diagnosis_lines(net, fault.t, hints=True)
        head += at_fault or ["  (no MIP_Sender, MIP_Receiver, MIP_Link or MIP_BufferSender in the PLCs)"]
    at_end = diagnosis_lines(net, None)
    if at_end:
        head.append(f"mip-kit: the blocks at the end ({fmt_t(net.now)}):")
        head += at_end
    sections, props = [], [("mip_fault_kind", "chain")] if chain is not None else []
    if net.trace_path is None or not net.trace_path.is_file():
        return head, sections, props
    net.flush_trace()
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    half = int(window_s * SEC / 2)
    # centred on the fault; near the start or the end, the whole window on the run's side
    t_from = max(0, min(fault.t - half, net.now - 2 * half))
    t_to = min(net.now, t_from + 2 * half)
    marks = [(fault.t, "radio", f"fault: record {fault.record}" if fault.record else "fault")]
    for plc, path, _, diag, vals, _ in observer(net).at(fault.t):
        kp = net.plcs.get(plc)
        side = "central" if kp is not None and kp.at == "mdp" else "outstation"
        waits = [(n, t) for n, t in diag if "WAIT" in n.upper()]
        text = ", ".join(f"{enum_name(t, v) if t.upper().startswith('E_') else f'{n}={v}'}"
                         for (n, t), v in zip(diag, vals) if (n, t) in waits)
        marks.append((fault.t, side, f"{path.rsplit('.', 1)[-1]}: {text}"))
    svg = net.diagram(outdir / "sequence-diagram.svg", station=fault.station,
                      window=(t_from, t_to), marks=marks,
                      title=f"{title}: {fault.text}"[:150])
    keep = int(max(TRACE_KEEP_S, window_s) * SEC)
    k_from, k_to = max(0, fault.t - keep), fault.t + keep
    raw = _window_lines(net.trace_path, k_from, k_to)
    gz = outdir / f"emulator-trace-{k_from // SEC}s-{min(k_to, net.now) // SEC}s.jsonl.gz"
    with gzip.open(gz, "wt", encoding="utf-8") as f:
        f.writelines(raw)
    around = trace_summary([l for l in raw if t_from <= int(re.match(r'\{"t":(\d+)', l).group(1)) <= t_to],
                           fault.station, limit=trace_lines, t_mark=fault.t)
    head.append(f"mip-kit: sequence diagram {fmt_t(t_from)} .. {fmt_t(t_to)}: {svg}")
    sections.append((f"radio and Modbus around the fault ({fmt_t(t_from)} .. {fmt_t(t_to)})",
                     "\n".join(around) or "(nothing on the radio)"))
    sections.append(("artifacts", f"diagram: {svg}\ntrace around the fault "
                                  f"({fmt_t(k_from)} .. {fmt_t(min(k_to, net.now))}): {gz}"))
    props += [("mip_fault", fault.text), ("mip_diagram", str(svg)), ("mip_trace", str(gz))]
    return head, sections, props
