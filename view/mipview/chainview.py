"""The whole chain of issue 35 in the page: the co-simulated chain (cosim/mipcosim/chain.py:
the relay, the outstation soft-PLC with MIP_SoeReader, the radio, the central soft-PLC with
MIP_Receiver and MIP_SoeServer, the SCADA stand-in polling it), stepped one scan tick at a time.

The diagram is the emulator's trace (the records and acknowledgements over the radio, labelled
as in every run: rows.py) with the chain's ends beside the middle hop, as notes at the PLC that
talks to them: the relay's events, the outstation's reads of the relay's recorder and its
acknowledgements to the relay (deleting the entries), at the outstation; the record handed over
to MIP_SoeServer, the SCADA's polls that took entries and its acknowledgements, at the central.
None of them is in the emulator's trace (the relay and the SCADA are not behind a modem): they
are read between two scan ticks from the chain's own counters (the relay's recorder, the
programs' status words %MW100.., the SCADA's store), the way docs/tools/chainseq.py draws one
event's trip.
"""
from __future__ import annotations

import ctypes
import json
from pathlib import Path

from .common import ViewError, diagram
from .live import Stepping, Windows
from .rows import History

CHAIN_TITLES = {
    "chain": "the chain: relay -> outstation -> radio -> central -> SCADA, 20 events",
    "chain-push": "the chain: relay -> outstation -> radio -> central -> WinCC OA, 20 events",
}


def entries(n):
    return f"{n} entry" if n == 1 else f"{n} entries"


class ChainLive(Stepping):
    """A run of the co-simulated chain the page drives (pause, step, speed; the chain's own
    faults are the chain tests', not the page's)."""

    mode = "live"

    def __init__(self, workdir: Path | None = None, events=20, handover="pull"):
        from chainsim import TRACE_FN              # docs/tools, on the path by .common
        from gen_traces import WORK
        from mipcosim import chain as C
        from mipcosim.sim import CosimError
        self.C = C
        self.push = handover == "push"
        self.preset_name = "chain-push" if self.push else "chain"
        self.title = CHAIN_TITLES[self.preset_name]
        self.workdir = (Path(workdir) if workdir else WORK) / "view-chain"
        self.n_events = events
        try:
            self.ch = C.SoeChain(C.ChainSetup(events=C.script(events, start_s=0.5),
                                              handover=handover,
                                              params=C.SoeParams(redundant=self.push)),
                                 self.workdir)
        except (CosimError, OSError) as e:
            raise ViewError(f"the chain: {e}") from None
        lib = self.ch.lib
        lib.mipemu_net_set_trace.argtypes = [ctypes.c_void_p, TRACE_FN, ctypes.c_void_p]
        lib.mipemu_net_set_trace.restype = None
        self.lines = []
        self._cb = TRACE_FN(lambda user, line, n: self.lines.append(
            json.loads(ctypes.string_at(line, n))))
        lib.mipemu_net_set_trace(lib.mipcosim_net(self.ch.sim), self._cb, None)
        self.paused = False
        self.speed = 1.0
        self.tick = self.ch.tick_ns
        self.history = History()
        self.windows = Windows()
        self._prev = self._counters()

    # ---------------------------------------------------------------- the simulation
    def _counters(self):
        ch, C = self.ch, self.C
        rs = ch.relay_stats()
        up = ch.up
        return {"generated": rs["generated"], "acknowledged": rs["acknowledged"],
                "entries": rs["entries"],
                "stored": ch.mw32("out", C.OUT_STORED) if up["out"] else None,
                "sent": ch.mw32("out", C.OUT_SENT) if up["out"] else None,
                "records": ch.mw32("cen", C.PUSH_RECORDS if self.push else C.CEN_RECORDS)
                if up["cen"] else None,
                # push: the events MIP_UnicosEvents framed; pull: handed over to MIP_SoeServer
                "put": ch.mw32("cen", C.PUSH_EVENTS if self.push else C.CEN_PUT)
                if up["cen"] else None,
                "acked": None if self.push else (ch.mw32("cen", C.CEN_ACKED) if up["cen"]
                                                 else None),
                "taken": len(ch.rows)}

    def _note(self, side, what, text):
        self.lines.append({"t": self.ch.now, "ev": "plc", "side": side, "what": what,
                           "text": text})

    def step(self):
        from mipcosim.sim import CosimError
        try:
            self.ch.run_for(self.tick)
        except CosimError as e:
            raise ViewError(f"the chain: {e}") from None
        cur, prev = self._counters(), self._prev
        self._prev = cur

        def more(k):
            return cur[k] is not None and prev[k] is not None and cur[k] > prev[k]
        if more("generated"):
            n = cur["generated"] - prev["generated"]
            self._note("outstation", "relay", f"relay: {n} event{'s' * (n > 1)} recorded "
                       f"({cur['entries']} in its recorder)")
        if more("stored"):
            n = cur["stored"] - prev["stored"]
            self._note("outstation", "relay", f"relay -> PLC: FC3 40601.., {entries(n)} read, "
                       f"stored in the logger (RETAIN)")
        if more("acknowledged"):
            n = cur["acknowledged"] - prev["acknowledged"]
            self._note("outstation", "relay", f"PLC -> relay: FC16 SOE_Control, {entries(n)} "
                       f"acknowledged, deleted at the relay")
        if more("sent"):
            self._note("outstation", "done", f"{entries(cur['sent'] - prev['sent'])} "
                       f"acknowledged by the central: out of the logger")
        if more("put") and not self.push:
            self._note("central", "deliver", f"{entries(cur['put'] - prev['put'])} handed "
                       f"over to MIP_SoeServer (not acknowledged yet: xAckByCaller)")
        if more("taken") and self.push:
            rows = self.ch.rows[prev["taken"]:cur["taken"]]
            for d in sorted({r["driver"] for r in rows}):
                vals = ", ".join(str(r["value"]) for r in rows if r["driver"] == d)
                self._note("central", "scada", f"central -> WinCC OA (UNICOS driver "
                           f"{d.upper()}): events pushed and answered (values {vals})")
        elif more("taken"):
            rows = self.ch.rows[prev["taken"]:cur["taken"]]
            vals = ", ".join(str(r["value"]) for r in rows)
            self._note("central", "scada", f"SCADA <- central: FC3 40601.., took "
                       f"{entries(len(rows))} (values {vals})")
        if more("acked"):
            self._note("central", "scada", "SCADA -> central: FC6 SOE_Control, taken: the "
                       "record's acknowledgement may go")

    @property
    def t_ns(self):
        return self.ch.now

    @property
    def done(self):
        return self.ch.finished()

    def _no(self, what):
        raise ViewError(f"{what}: not in the chain's run (its faults are the chain tests', "
                        f"docs/chain.md)")

    def set_loss(self, direction, p):
        self._no("extra loss")

    def lose(self, what):
        self._no("lose")

    def restart(self, name, kind="cold", outage_ms=1000):
        self._no("restart")

    # ---------------------------------------------------------------- what the page shows
    def _blocks(self):
        c = self._prev
        relay = [("events recorded", c["generated"]), ("entries in the recorder", c["entries"]),
                 ("entries acknowledged", c["acknowledged"])]
        out = [("entries read and stored", c["stored"]), ("entries acknowledged by the central",
                                                           c["sent"])]
        if self.push:
            cen = [("records received", c["records"]), ("events framed", c["put"])]
            scada = [("events at the drivers (A and B)", c["taken"]),
                     ("of events (each to both)", self.n_events)]
        else:
            cen = [("records received", c["records"]), ("entries handed over", c["put"]),
                   ("records acknowledged", c["acked"])]
            scada = [("entries taken", c["taken"]), ("of events", self.n_events)]
        return [{"side": side, "block": block, "off": False,
                 "head": {"relay": "relay", "scada": "control system"}.get(side, f"{side} PLC"),
                 "vars": [{"name": k, "value": "-" if v is None else v, "tip": ""}
                          for k, v in rows]}
                for side, block, rows in (("relay", "SIPROTEC event recorder", relay),
                                          ("outstation", "MIP_SoeReader, MIP_Sender", out),
                                          ("central", "MIP_Receiver, " + (
                                              "MIP_UnicosEvents" if self.push else
                                              "MIP_SoeServer"), cen),
                                          ("scada", "WinCC OA's UNICOS drivers (mippeer.unicos)"
                                           if self.push else "SCADA stand-in (mippeer.scada)",
                                           scada))]

    def state(self):
        dg = diagram(self.history, self.lines, f"{self.title} (live)")
        s1 = self.ch.radio_stats()
        return {
            "mode": self.mode, "chain": True, "preset": self.preset_name, "title": self.title,
            "mipsim": "the whole chain in the co-simulation (cosim/mipcosim/chain.py): make "
                      "run RUN_ARGS=--chain in virtual time",
            "t_ms": self.t_ms, "paused": self.paused, "speed": self.speed,
            "extra_loss": {"up": 0.0, "down": 0.0},
            "lose_next": {"record": False, "ack": False},
            "done": self.done, **dg, "blocks": self._blocks(),
            "registers": self.windows.peek(self.ch.lib, self.ch.lib.mipcosim_net(self.ch.sim)),
            "radio": {"down": s1.get("tel_down", 0), "up": s1.get("tel_up", 0),
                      "lost_down": s1.get("lost_down", 0), "lost_up": s1.get("lost_up", 0)},
            "off": {},
        }

    def trace(self):
        return [json.dumps(d) for d in self.lines]

    def close(self):
        self.ch.close()


class ChainFiles:
    """The ends of the real-time chain demo (plc/demo.py --chain, mipdemo.chain) beside its emulator trace: the
    relay's script (events.txt: each event's time on the relay's clock, which starts with the
    emulator, so with the trace's) and the SCADA's store (scada-entries.jsonl: the entries it
    took, in order, without a time: each is drawn at the trace's time when the view first read
    it, so a post-mortem draws them all at the end). Neither is in the emulator's trace (the
    relay's requests and the SCADA's polls do not pass a modem)."""

    def __init__(self, trace: Path):
        d = Path(trace).parent
        self.script, self.store = d / "events.txt", d / "scada-entries.jsonl"
        self.relay = self._script()
        self.taken = []                 # (t_ns seen, entry)
        self._pos = 0

    @staticmethod
    def present(trace: Path):
        return (Path(trace).parent / "events.txt").is_file()

    def _script(self):
        out = []
        try:
            text = self.script.read_text(errors="replace")
        except OSError:
            return out
        for line in text.splitlines():
            words = line.split()
            try:
                out.append((int(round(float(words[0]) * 1e9)), int(words[4], 0)))
            except (IndexError, ValueError):
                continue                # not an event line: the relay says why, not the view
        return out

    def poll(self, t_now):
        """Reads the SCADA's new entries; True if any."""
        try:
            with open(self.store, "rb") as f:
                f.seek(self._pos)
                chunk = f.read()
        except OSError:
            return False
        end = chunk.rfind(b"\n") + 1
        self._pos += end
        new = False
        for raw in chunk[:end].splitlines():
            try:
                e = json.loads(raw)
            except ValueError:
                continue
            if isinstance(e, dict):
                self.taken.append((t_now, e))
                new = True
        return new

    def lines(self, t_now):
        """The chain's ends as notes, up to the trace's time t_now."""
        out = [{"t": t, "ev": "plc", "side": "outstation", "what": "relay",
                "text": f"relay: event recorded (value {v})"} for t, v in self.relay if t <= t_now]
        groups = {}
        for t, e in self.taken:
            groups.setdefault(t, []).append(e)
        for t, es in groups.items():
            vals = ", ".join(str(e.get("value")) for e in es)
            out.append({"t": t, "ev": "plc", "side": "central", "what": "scada",
                        "text": f"SCADA took {entries(len(es))} (values {vals}), "
                                f"seen by the view at this time"})
        return out


def merged(events, ends):
    """The trace's lines and the chain's ends, in time order (a trace line first at a tie)."""
    if not ends:
        return events
    t_now = events[-1]["t"] if events else 0
    extra = ends.lines(t_now)
    return sorted(events + extra, key=lambda d: d["t"]) if extra else events
