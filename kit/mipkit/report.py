"""The kit's failure report: what went wrong first, in the integrator's record numbers, with
the blocks' own diagnosis and the radio traffic around that moment (docs/test-kit.md,
"When a test fails").

- Blocks are found in each PLC by type: every instance whose members are the interface (the
  VAR_INPUT and VAR_OUTPUT names) of MIP_Sender, MIP_Receiver, MIP_Link or MIP_BufferSender,
  read from st_lib's own ST; its diagnosis outputs (eState, eWaitReason, wWaitFor, eErrorId;
  MIP_Link's per side) are shown with the enum names of st_lib's MIP_Types.st
  (mipcosim.programs.st_enums, the one reader of them).
- An Observer samples them (and each peer's accepted records) every 100 ms of virtual time,
  so the report can say what the blocks did at the fault, not only at the end.
- The fault is the record a failure names ("record 7: ..."), else the first record a peer did
  not get; its moment is when the peer accepted it, else when progress stopped.
"""
from __future__ import annotations

import functools
import json
import re
from dataclasses import dataclass

from .base import MS, SCAN_FN, SEC

BLOCK_TYPES = ("MIP_Sender", "MIP_Receiver", "MIP_Link", "MIP_BufferSender")
_DIAG = re.compile(r"e\w*State|e\w*WaitReason|w\w*WaitFor|e\w*ErrorId", re.I)
_ORDER = ("STATE", "WAITREASON", "WAITFOR", "ERRORID")
OBSERVE_MS = 100
# the output that counts the records a receiving block delivered to its program
RECORDS_DELIVERED = {"MIP_Receiver": "UDIRECORDS", "MIP_Link": "UDIRECORDSRECEIVED"}
TRACE_KEEP_S = 30.0        # virtual seconds of the trace kept each side of the fault (a
                           # failure's artifacts stay under 200 KB)


def fmt_t(ns):
    """Virtual time for people: 0.030 s, 12.345 s, 1534.2 s."""
    s = ns / SEC
    return f"{s:.3f} s" if s < 1000 else f"{s:.1f} s"


# ---------------------------------------------------------------- the blocks, by type

def _st_lib():
    """The core library's folder (the blocks of BLOCK_TYPES are the core's)."""
    from mipcosim import programs as L
    return L.ST_LIB / "core"


@functools.lru_cache(maxsize=None)
def signatures():
    """{block type: (interface names (upper case), [(diagnosis output, its declared type)])}
    from st_lib's ST sources."""
    out = {}
    for t in BLOCK_TYPES:
        text = re.sub(r"\(\*.*?\*\)", " ", (_st_lib() / f"{t}.st").read_text(encoding="utf-8"),
                      flags=re.S)
        m = re.search(rf"\bFUNCTION_BLOCK\s+{t}\b(.*?)\bEND_FUNCTION_BLOCK\b", text, re.S)
        names, diag = set(), []
        for kind, body in re.findall(r"\b(VAR_INPUT|VAR_OUTPUT)\b(.*?)\bEND_VAR\b", m.group(1), re.S):
            for decl in body.split(";"):
                if ":" not in decl:
                    continue
                left, typ = decl.split(":", 1)
                typ = typ.split(":=")[0].strip()
                for n in (x.strip() for x in left.split(",")):
                    if not n:
                        continue
                    names.add(n.upper())
                    if kind == "VAR_OUTPUT" and _DIAG.fullmatch(n):
                        diag.append((n, typ))
        diag.sort(key=lambda d: next(i for i, k in enumerate(_ORDER) if d[0].upper().endswith(k)))
        out[t] = (frozenset(names), diag)
    return out


@functools.lru_cache(maxsize=None)
def _enums():
    from mipcosim import programs as L
    return {k.upper(): v for k, v in L.st_enums().items()}


def enum_name(type_name, value):
    names = _enums().get(type_name.upper())
    if names is None:
        return str(value)
    return names[value] if isinstance(value, int) and 0 <= value < len(names) else f"#{value}"


def find_blocks(symbols, programs=None):
    """[(instance path, block type, [(output, declared type)])] of every MIP block instance in
    a build's symbols (outermost only: a MIP_Link's own sender and receiver are its parts)."""
    members = {}
    for s in symbols:
        parent, _, name = s.path.rpartition(".")
        members.setdefault(parent, set()).add(name)
    sigs = signatures()
    found = {}
    for parent, names in members.items():
        fits = [t for t, (sig, _) in sigs.items() if sig <= names]
        if fits:
            found[parent] = max(fits, key=lambda t: len(sigs[t][0]))
    out = []
    for path in sorted(found):
        if any(path.startswith(p + ".") for p in found):
            continue
        out.append((path, found[path], sigs[found[path]][1]))
    return out


def display_path(path, programs):
    """CONFIG0.RES0.STATION.SND as FIELDSTATION.SND (the program type, as the harness takes it)."""
    for inst, ptype in (programs or {}).items():
        if path.startswith(inst + "."):
            return ptype + path[len(inst):]
    return path


def describe(values, diag):
    return " ".join(f"{n}={enum_name(t, v) if t.upper().startswith('E_') else v}"
                    for (n, t), v in zip(diag, values))


# ---------------------------------------------------------------- the observer

class Observer:
    """A process in the network's virtual time (every OBSERVE_MS) that notes each block's
    diagnosis when it changes, and the records each peer accepted and each MIP_Receiver /
    MIP_Link of the PLCs delivered (an integrator's own central), when the count changes."""

    def __init__(self, net, period_ms=OBSERVE_MS):
        self.net = net
        self.history = {}       # (plc name, instance path) -> [(t, values)]
        self.accepted = {}      # peer name or "plc PATH" -> [(t, records accepted)]
        self._vars = {}         # plc name -> (plc object, [(path, type, diag, [_Var])])
        self.failed = None
        self._fn = SCAN_FN(self._tick)
        self.pid = net.kernel.add_scan(self._fn, int(period_ms * MS))

    def _tick(self, _rt, _n):
        try:
            self.sample()
        except Exception as e:  # noqa: BLE001 - a report helper never stops the run
            self.failed = e
        return 0

    def blocks(self, kp):
        """[(instance path, type, diag, vars)] of a KitPlc's live instance."""
        cached = self._vars.get(kp.name)
        if cached is None or cached[0] is not kp.plc:
            res = kp.result
            blocks = []
            for path, typ, diag in find_blocks(res.symbols, res.programs):
                try:
                    vs = [kp.plc._lookup(f"{path}.{n}") for n, _ in diag]
                except Exception:  # noqa: BLE001 - a member the harness cannot read
                    continue
                count = RECORDS_DELIVERED.get(typ)
                try:
                    count = kp.plc._lookup(f"{path}.{count}") if count else None
                except Exception:  # noqa: BLE001
                    count = None
                blocks.append((path, typ, diag, vs, count))
            cached = (kp.plc, blocks)
            self._vars[kp.name] = cached
        return cached[1]

    def sample(self):
        now = self.net.now
        for name, kp in self.net.plcs.items():
            if kp.plc is None:
                continue
            for path, _, _, vs, count in self.blocks(kp):
                vals = tuple(v.read() for v in vs)
                h = self.history.setdefault((name, path), [])
                if not h or h[-1][1] != vals:
                    h.append((now, vals))
                if count is not None:
                    n = count.read()
                    a = self.accepted.setdefault(f"{name} {display_path(path, kp.result.programs)}", [])
                    if (a[-1][1] if a else 0) != n:
                        a.append((now, n))
        for name, p in self.net.peers.items():
            r = p.peer.receiver
            n = (sum(len(t) for t in r.transfers) + len(r.current)) if r is not None else 0
            a = self.accepted.setdefault(name, [])
            if (a[-1][1] if a else 0) != n:
                a.append((now, n))

    def at(self, t):
        """[(plc, path, type, diag, values, since)] at virtual time t (None: now)."""
        out = []
        for name, kp in self.net.plcs.items():
            if kp.plc is None:
                continue
            for path, typ, diag, _, _ in self.blocks(kp):
                h = self.history.get((name, path), [])
                i = len(h) - 1 if t is None else max((k for k, (ht, _) in enumerate(h) if ht <= t),
                                                      default=-1)
                if i < 0:
                    continue
                out.append((name, display_path(path, kp.result.programs), typ, diag, h[i][1], h[i][0]))
        return out

    def stuck_since(self):
        """When the blocks last changed (the earliest of their last changes: the first that
        stopped moving), or None."""
        lasts = [h[-1][0] for h in self.history.values() if h]
        return min(lasts) if lasts else None


def observer(net):
    """The network's Observer, added at its first run (kit/mipkit/net.py calls this)."""
    obs = getattr(net, "_observer", None)
    if obs is None:
        obs = net._observer = Observer(net)
    return obs


# ---------------------------------------------------------------- the fault

@dataclass
class Fault:
    record: int | None       # the integrator's record number (the peer's count, 1-based)
    t: int                   # its moment (virtual ns)
    text: str                # one line: what happened to it
    station: int = 1


def _transfer_of(peer, n):
    """(transfer, its record number on the radio) of the n-th record a peer accepted."""
    r = peer.peer.receiver
    if r is None:
        return None
    lens = [len(t) for t in r.transfers] + [len(r.current)]
    done = len(r.transfers)
    for k, ln in enumerate(lens, 1):
        if n <= ln:
            radio = "16#FFFF" if k <= done and n == ln else str(n)
            return k, radio
        n -= ln
    return None


def _carried(net, station, radio, t_seen):
    """The last telegram of `station` before t_seen (the observer's moment) that carried the
    block of radio record number `radio` (its first register), or None."""
    if not net.trace_path.is_file():
        return None
    net.flush_trace()
    want = 65535 if radio == "16#FFFF" else int(radio)
    best = None
    for line in _window_lines(net.trace_path, max(0, t_seen - 10 * SEC), t_seen):
        if '"ev":"radio"' not in line or '"regs":0,' in line:
            continue
        d = json.loads(line)
        if d.get("st") == station and d.get("r0") == want and d.get("regs", 0) > 1:
            best = d["t"]
    return best


def _plc_fault(obs, sink, named, t_hint, station, net):
    """The fault at a PLC's receiving block (sink: "plc PATH"), in the records it delivered."""
    acc = obs.accepted[sink]
    got = acc[-1][1] if acc else 0
    if named is not None and named <= got:
        t = next((t for t, n in acc if n >= named), net.now)
        return Fault(named, t, f"record {named}: {sink} delivered it by {fmt_t(t)} (sampled "
                               f"every {OBSERVE_MS} ms)", station)
    n = named if named is not None else got + 1
    t = t_hint if t_hint is not None else (acc[-1][0] if acc else (obs.stuck_since() or 0))
    last = f", the last at {fmt_t(acc[-1][0])}" if acc else ""
    return Fault(n, t, f"record {n}: never delivered by {sink} (it delivered {got} "
                       f"record{'s' if got != 1 else ''}{last})", station)


def _raw_position(peer, records, i):
    """The position (1-based) in the peer's receiver of records[i - 1]."""
    r = peer.peer.receiver
    raw = [p for t in r.transfers for p in t] + list(r.current)
    if len(raw) == len(records):
        return i
    target = records[i - 1]
    return next((j for j, p in enumerate(raw, 1) if p is target), i)


def find_fault(net, message, t_hint=None):
    """The first record that went wrong and its moment, from the failure's message and what
    the observer saw."""
    obs = observer(net)
    obs.sample()
    m = re.search(r"\brecord (\d+)\b", message or "")
    named = int(m.group(1)) if m else None
    peers = [p for p in net.peers.values() if p.peer.receiver is not None]   # receiving ones
    peer = max(peers, key=lambda p: (obs.accepted.get(p.name) or [(0, 0)])[-1][1]) if peers else None
    station = next((p.at for p in list(net.plcs.values()) + list(net.peers.values())
                    if isinstance(p.at, int)), 1)
    if peer is None:
        # an integrator's own central: the records its MIP_Receiver (MIP_Link) delivered
        sinks = [k for k in obs.accepted if k not in net.peers]
        if sinks:
            return _plc_fault(obs, max(sinks, key=lambda k: obs.accepted[k][-1][1]
                                       if obs.accepted[k] else 0), named, t_hint, station, net)
        t = t_hint if t_hint is not None else (obs.stuck_since() or net.now)
        text = f"record {named}: see the failure below" if named else "the failure below"
        return Fault(named, t, text, station)
    acc = obs.accepted.get(peer.name, [])
    # the test's numbers are those of peer.records; the observer counts what the peer's
    # receiver holds (the same records, and any a records view leaves out)
    records = peer.records
    got = len(records)
    if named is not None and named <= got:
        j = _raw_position(peer, records, named)
        t = next((t for t, n in acc if n >= j), net.now)
        where = _transfer_of(peer, j)
        if where and net.trace_path is not None:
            t = _carried(net, station, where[1], t) or t
        radio = f" (transfer {where[0]}, record {where[1]} on the radio)" if where else ""
        return Fault(named, t, f"record {named}{radio}: {peer.name} accepted it at {fmt_t(t)}",
                     station)
    if t_hint is not None:
        t = t_hint
    elif acc:
        t = acc[-1][0]
    else:
        t = obs.stuck_since() or 0
    last = f", the last at {fmt_t(acc[-1][0])}" if acc else ""
    r = peer.peer.receiver
    if named is None and r.transfers and not r.current:
        # every transfer the peer began it completed: no record is missing there
        k = len(r.transfers)
        return Fault(None, t, f"no record missing: {peer.name} accepted {got} "
                              f"record{'s' if got != 1 else ''} in {k} complete "
                              f"transfer{'s' if k != 1 else ''}{last}", station)
    n = named if named is not None else got + 1
    return Fault(n, t, f"record {n}: never reached {peer.name} (it accepted {got} "
                       f"record{'s' if got != 1 else ''}{last})", station)


# what a wait reason that does not end usually means in an integrator's project
HINTS = {
    "MIP_WAIT_SNAPSHOT": "with xRetained := TRUE the block waits until a RETAIN snapshot holds "
                         "its state (wSnapshots changes): does the plcrt config have a [retain] "
                         "section whose request and saved are the program's?",
    "MIP_WAIT_WRITE": "the write handshake's done or error never came: the config's write range "
                      "(trigger, done, error) and the program's copies",
    "MIP_WAIT_LINK": "the program's reads of its own modem fail (xReadError; xLinkError and "
                     "wLinkError say why): the config's read range and device",
}


def diagnosis_lines(net, t=None, hints=False):
    out, seen = [], set()
    for plc, path, typ, diag, vals, since in observer(net).at(t):
        text = describe(vals, diag)
        out.append(f"  {plc} {path} ({typ}): {text} (since {fmt_t(since)})")
        for name, hint in HINTS.items():
            if hints and f"={name}" in text and name not in seen:
                seen.add(name)
                out.append(f"    {name}: {hint}")
    return out


# ---------------------------------------------------------------- the trace, readable

def _interesting(d):
    ev = d.get("ev")
    if ev == "radio":
        return bool(d.get("regs") or d.get("kind") == "ack" or d.get("ack"))
    if ev == "modbus":
        return d.get("fc") != 3 or bool(d.get("exc")) or "close" in d
    return True


def _line(d):
    t = fmt_t(d["t"]).rjust(11)
    ev = d.get("ev")
    if ev == "radio":
        st = d.get("st")
        arrow = f"MDP -> station {st}" if d.get("dir") == "down" else f"station {st} -> MDP"
        regs = d.get("regs", 0)
        body = f"block [0]={d.get('r0')} ({regs} register{'s' if regs != 1 else ''})" if regs \
            else ("confirms the block" if d.get("kind") == "ack" or d.get("ack") else "empty")
        return f"{t}  radio {arrow}: {d.get('kind')}, {body}" + (": LOST" if d.get("lost") else "")
    if ev == "modbus":
        who = "MDP" if d.get("ep") == "mdp" else f"TRM station {d.get('st')}"
        if "close" in d:
            return f"{t}  Modbus at the {who}: frame closed: {d['close']}"
        if d.get("exc"):
            return f"{t}  Modbus at the {who}: FC{d.get('fc')} at {d.get('wa', d.get('ra'))}: exception {d['exc']:02X}"
        wq = d.get("wq")
        return f"{t}  Modbus at the {who}: FC{d.get('fc')} write at {d.get('wa')}: [0]={d.get('w0')} " \
               f"({wq} register{'s' if wq != 1 else ''})"
    if ev == "station":
        return f"{t}  station {d.get('st')} {d.get('state')}"
    rest = {k: v for k, v in d.items() if k not in ("t", "seq", "ev", "_line")}
    return f"{t}  {ev}: {rest}"


def _window_lines(path, t_from, t_to):
    """The trace's lines in [t_from, t_to] (raw text)."""
    out = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            m = re.match(r'\{"t":(\d+)', line)
            if not m:
                continue
            t = int(m.group(1))
            if t < t_from:
                continue
            if t > t_to:
                break
            out.append(line)
    return out


def trace_summary(lines, station=None, limit=40, t_mark=None):
    """Readable lines of a trace window: times in s, empty polls and plain reads folded; at
    most `limit` lines, centred on t_mark (marked "<- the fault")."""
    out, folded, lost, f_from, f_to = [], 0, 0, None, None
    mark = None

    def flush():
        nonlocal folded, lost
        if folded:
            out.append(f"{'':11}  ... {folded} empty polls/answers"
                       f"{f' ({lost} lost)' if lost else ''} and reads "
                       f"({fmt_t(f_from)} .. {fmt_t(f_to)})")
            folded = lost = 0

    for line in lines:
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            continue
        if station is not None and d.get("st") not in (None, station):
            continue
        if not _interesting(d):
            if not folded:
                f_from = d["t"]
            folded, f_to = folded + 1, d["t"]
            lost += bool(d.get("lost"))
            continue
        flush()
        if mark is None and t_mark is not None and d["t"] >= t_mark:
            mark = len(out)
            out.append(_line(d) + "   <- the fault")
        else:
            out.append(_line(d))
    flush()
    if len(out) > limit:
        c = mark if mark is not None else len(out) // 2
        lo = max(0, min(c - limit // 2, len(out) - limit))
        hi = lo + limit
        out = ([f"{'':11}  ... {lo} lines before ..."] if lo else []) + out[lo:hi] + \
              ([f"{'':11}  ... {len(out) - hi} lines after ..."] if hi < len(out) else [])
    return out
