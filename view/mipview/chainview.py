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
        from mipdocs.gen_traces import WORK
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
        self.lines = []
        self.ch.kernel.on_trace(lambda line: self.lines.append(line))
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
            "registers": self.windows.peek(self.ch.kernel.lib, self.ch.kernel.net),
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
    took, in order, each with `mono_ns`, when it took them on CLOCK_MONOTONIC; the trace's first
    "relay" line gives that clock's value at the trace's time 0, so each poll is drawn at its
    time; an entry without it (an older file) is drawn when the view first read it); with
    --handover push, WinCC OA's drivers' file instead (unicos-events.jsonl, mippeer.unicos
    --out: each event with its driver, A or B, and `mono_ns` the same way). The
    relay's reads and acknowledgements are in the trace itself ("relay" lines of mip-emulator
    --relay: relay_notes)."""

    def __init__(self, trace: Path):
        d = Path(trace).parent
        self.script, self.store = d / "events.txt", d / "scada-entries.jsonl"
        self.pushes = d / "unicos-events.jsonl"     # the push way: WinCC OA's drivers A and B
        self.relay = self._script()
        self.taken = []                 # (mono_ns or None, t_ns seen, entry)
        self.pushed = []                # the same, of the drivers' events
        self._pos = {}

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
        """Reads the SCADA's new entries and the drivers' new events; True if any."""
        a = self._read(self.store, self.taken, t_now, lambda e: True)
        b = self._read(self.pushes, self.pushed, t_now,
                       lambda e: e.get("kind") == "event" and e.get("driver") in ("A", "B")
                       and isinstance(e.get("value"), int))
        return a or b

    def _read(self, path, into, t_now, wanted):
        try:
            with open(path, "rb") as f:
                f.seek(self._pos.get(path, 0))
                chunk = f.read()
        except OSError:
            return False
        end = chunk.rfind(b"\n") + 1
        self._pos[path] = self._pos.get(path, 0) + end
        new = False
        for raw in chunk[:end].splitlines():
            try:
                e = json.loads(raw)
            except ValueError:
                continue
            if isinstance(e, dict) and wanted(e):
                m = e.get("mono_ns")
                into.append((m if isinstance(m, int) and not isinstance(m, bool) else None,
                             t_now, e))
                new = True
        return new

    def lines(self, t_now, origin=None):
        """The chain's ends as notes, up to the trace's time t_now; origin: CLOCK_MONOTONIC at
        the trace's time 0 (None: not in the trace)."""
        out = [{"t": t, "ev": "plc", "side": "outstation", "what": "relay",
                "text": f"relay: event recorded (value {v})"} for t, v in self.relay if t <= t_now]
        groups = {}
        for m, seen, e in self.taken:
            at = m - origin if m is not None and origin is not None and m >= origin else None
            groups.setdefault((at, seen if at is None else None), []).append(e)
        for (at, seen), es in groups.items():
            vals = ", ".join(str(e.get("value")) for e in es)
            if at is not None:
                text = f"SCADA <- central: FC3 40601.., took {entries(len(es))} (values {vals})"
            else:
                at, text = seen, (f"SCADA took {entries(len(es))} (values {vals}), seen by the "
                                  f"view at this time")
            out.append({"t": at, "ev": "plc", "side": "central", "what": "scada", "text": text})
        from mippeer.unicos import SUB_EVENTS32
        groups = {}
        for m, seen, e in self.pushed:
            at = m - origin if m is not None and origin is not None and m >= origin else None
            groups.setdefault((e["driver"], at, seen if at is None else None), []).append(e)
        for (drv, at, seen), es in groups.items():
            # a 32-bit event's value: type / bit offset in the high word (docs/chain.md)
            vals = ", ".join(str(e.get("value", 0) & 0xFFFF if e.get("sub") == SUB_EVENTS32
                                 else e.get("value")) for e in es)
            text = (f"central -> WinCC OA (UNICOS driver {drv}): events pushed and answered "
                    f"(values {vals})")
            if at is None:
                at, text = seen, text + ", seen by the view at this time"
            out.append({"t": at, "ev": "plc", "side": "central", "what": "scada", "text": text})
        return out


def relay_origin(events):
    """CLOCK_MONOTONIC at the trace's time 0, from mip-emulator's first "relay" line (None)."""
    for d in events[:8]:
        if d.get("ev") == "relay" and d.get("start") and isinstance(d.get("mono_ns"), int):
            return d["mono_ns"]
    return None


def relay_notes(events):
    """The relay's "relay" trace lines (mip-emulator --relay --trace) as the notes the chain
    preset draws at the outstation: a read that showed offered entries, an acknowledgement."""
    out = []
    for d in events:
        if d.get("ev") != "relay" or d.get("start"):
            continue
        fc, left = d.get("fc"), d.get("entries")
        if not all(isinstance(d.get(k, 0), int) for k in ("fc", "offered", "soe", "w0", "exc",
                                                           "acked")):
            continue                    # not one mip-emulator writes: nothing to draw
        if fc == 3:
            n = d.get("offered", 0)
            text = (f"relay -> PLC: FC3 40601.., {entries(n)} offered (SOE_Control "
                    f"16#{d.get('soe', 0):04X}, {left} in its recorder)")
        elif d.get("exc"):
            text = (f"PLC -> relay: FC{fc} SOE_Control 16#{d.get('w0', 0):04X} refused "
                    f"(exception {d['exc']:02d})")
        else:
            text = (f"PLC -> relay: FC{fc} SOE_Control, {entries(d.get('acked', 0))} "
                    f"acknowledged, deleted at the relay ({left} left)")
        out.append({"t": d["t"], "ev": "plc", "side": "outstation", "what": "relay",
                    "text": text})
    return out


def merged(events, ends):
    """The trace's lines, the relay's handshake in them as notes and the chain's ends, in time
    order (a trace line first at a tie)."""
    extra = relay_notes(events)
    if ends:
        extra += ends.lines(events[-1]["t"] if events else 0, relay_origin(events))
    return sorted(events + extra, key=lambda d: d["t"]) if extra else events
