"""A radio network in virtual time with the user's soft-PLCs and note-following peers on it.

One model of each thing: the kernel is mipcosim's (libmipcosim.so: the emulator core and the
lockstep loop), the PLCs are plcharness's, the peer is mippeer's; this module only wires the
user's programs and configs to stations, and adds faults and the failure report.
"""
from __future__ import annotations

import collections
import json
import re
from pathlib import Path

from mipcosim import sim as S
from . import capture
from .base import FAST, MS, REALISTIC, SEC, KitError
from .program import build, check_config
from .stations import KitPeer, KitPlc


class Net:
    """An MDP-810 and `stations` TRM-810s in virtual time; add PLCs and peers, run, read."""

    def __init__(self, workdir, stations=1, *, radio="fast", bitrate=None, slot_gap_ms=None,
                 overhead_bytes=None, loss_down=0.0, loss_up=0.0, burst=0.0, seed=1,
                 static=False, static_registers=123, compiler="stc", trace=True,
                 semantics=None, capture_s=None):
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        base = {"fast": FAST, "realistic": REALISTIC}.get(radio)
        if base is None:
            raise KitError(f"radio {radio!r}: use fast or realistic (or give bitrate, slot_gap_ms)")
        self.radio = {"bitrate": bitrate or base["bitrate"],
                      "slot_gap_ms": base["slot_gap_ms"] if slot_gap_ms is None else slot_gap_ms,
                      "overhead_bytes": overhead_bytes or base["overhead_bytes"]}
        if not 1 <= stations <= 247:
            raise KitError(f"stations {stations}: one MDP-810 serves 1..247")
        for n, v in (("loss_down", loss_down), ("loss_up", loss_up)):
            if not 0.0 <= v < 1.0:
                raise KitError(f"{n} {v}: a probability in 0..1 (1 excluded)")
        self.stations, self.compiler, self.seed = stations, compiler, seed
        self.semantics = semantics
        self.trace_path = self.workdir / "emulator-trace.jsonl" if trace else None
        self.kernel = S.Kernel(stations, static=static, static_registers=static_registers,
                               loss_down=loss_down, loss_up=loss_up, burst=burst, seed=seed,
                               radio=S.Radio(self.radio["bitrate"],
                                             int(self.radio["slot_gap_ms"] * MS),
                                             self.radio["overhead_bytes"]),
                               trace=self.trace_path, error=KitError)
        self.lib = self.kernel.lib
        # the Modbus traffic; a failure's pcapng holds capture_s seconds of it (capture.py)
        self.capture = capture.ModbusCapture(capture_s) if capture_s else None
        self.plcs: dict[str, KitPlc] = {}
        self.peers: dict[str, KitPeer] = {}
        self.ends: dict = {}        # name -> KitRelay / KitUnicos (ends.py)
        self._losses = []           # [station, up, record or None, times left]
        self._lost = []             # (virtual ns, station, "up"/"down", record)
        self._fate = None
        self._end = 0
        self._free_slots = list(range(63, -1, -1))   # the kernel's tap slots (delivery taps)

    # ------------------------------------------------------------------ set-up

    @property
    def sim(self):
        if self.kernel.closed:
            raise KitError("the network is closed")
        return self.kernel.handle

    @property
    def now(self):
        return self.kernel.now

    def _check(self, rc):
        self.kernel.check(rc)

    def _where(self, at):
        if at == "mdp" or at == "MDP":
            return "mdp"
        if isinstance(at, int) and not isinstance(at, bool) and 1 <= at <= self.stations:
            return at
        raise KitError(f"station {at!r}: the network has stations 1..{self.stations} and the mdp")

    def _name(self, name):
        if name in self.plcs or name in self.peers or name in self.ends:
            raise KitError(f"{name}: already on the network")
        return name

    def plc(self, name, sources, config, at, retain_period_ms=None, compiler=None):
        """The user's program (ST sources, the CONFIGURATION last) with its plcrt config,
        attached to station `at` (1..N: that station's TRM-810) or "mdp" (the MDP-810): every
        device of the config talks to that modem. RETAIN snapshots every retain_period_ms
        (default: the config's [retain] period, else 1000)."""
        name, at = self._name(name), self._where(at)
        config = Path(config)
        if not config.is_file():
            raise KitError(f"{config}: error: no such config")
        result = build(sources, self.workdir, compiler or self.compiler, semantics=self.semantics)
        check_config(result, config)
        p = KitPlc(self, name, result, config, at, retain_period_ms)
        try:
            p._start()
        except Exception as e:  # noqa: BLE001 - plcharness / plcrt: one line
            if "common_ticktime__" in str(e):
                raise KitError(f"{name}: the program's CONFIGURATION has no TASK with an INTERVAL: "
                               "give one, e.g. TASK tMain(INTERVAL := T#10ms, PRIORITY := 0); "
                               "PROGRAM p WITH tMain : YourProgram;") from None
            raise KitError(f"{name}: {e}") from None
        self.plcs[name] = p
        return p

    def peer(self, name="peer", at="mdp", role=None, records=None, lenient=False, layout="uni",
             drive="spontaneous", period_ms=50, retransmit_s=2.0, request_s=1.0,
             static_registers=0, unit=1):
        """A peer written from the note (strict, or lenient) on modem `at`: role central at the
        MDP (unit = the station it talks to), outstation at a station."""
        name, at = self._name(name), self._where(at)
        role = role or ("central" if at == "mdp" else "outstation")
        if at == "mdp":
            self._where(unit)      # the MDP's unit id is the station it talks to
        p = KitPeer(self, name, at, role, records, lenient, layout, drive, period_ms,
                    retransmit_s, request_s, static_registers, unit)
        self.peers[name] = p
        return p

    def _plc_of(self, plc, what):
        if isinstance(plc, KitPlc):
            return plc
        if plc in self.plcs:
            return self.plcs[plc]
        raise KitError(f"{what}: no PLC {plc!r} on the network (have: "
                       f"{', '.join(self.plcs) or 'none'})")

    def relay(self, name="relay", plc=None, device="relay", events=(), **kw):
        """A SIPROTEC relay (the emulator's, in virtual time) as device `device` of PLC `plc`
        (a KitPlc or its name) instead of a modem: scripted events [(t_s, [type/bit, address,
        cause/type, value]), ...], rate, burst = (n, every_s), base (600), capacity (200),
        overflow ("drop-oldest" | "drop-new"), seq_bits, bad_ack, origin_ms (the time stamp
        of virtual time 0). Give it before the network runs. Returns a KitRelay."""
        from .ends import KitRelay
        name = self._name(name)
        r = KitRelay(self, name, self._plc_of(plc, f"relay {name}"), device, events, **kw)
        self.ends[name] = r
        return r

    def unicos(self, name="unicos", plc=None, device="unicos", device_b=None, **kw):
        """WinCC OA's Modbus driver in UNICOS mode (peers/mippeer/unicos.py) as device
        `device` of PLC `plc`, with device_b a redundant pair's driver B: marker (16#FFFF),
        little_endian_register, down / down_b = [(from_s, to_s), ...] virtual seconds without
        an answer. Give it before the network runs. Returns a KitUnicos."""
        from .ends import KitUnicos
        name = self._name(name)
        try:
            u = KitUnicos(self, name, self._plc_of(plc, f"unicos {name}"), device, device_b, **kw)
        except TypeError as e:
            raise KitError(f"unicos {name}: {e}") from None
        self.ends[name] = u
        return u

    def scada(self, name="scada", plc=None, **kw):
        """A SCADA polling PLC `plc`'s Modbus slave (its config's [slave]; the program's
        MIP_SoeServer) through the SOE handshake (peers/mippeer/scada.py), in virtual time:
        base (600), poll_ms (100), reack (1.0 s), down = [(from_s, to_s), ...] without polls.
        Returns a KitScada."""
        from .ends import KitScada
        name = self._name(name)
        try:
            s = KitScada(self, name, self._plc_of(plc, f"scada {name}"), **kw)
        except TypeError as e:
            raise KitError(f"scada {name}: {e}") from None
        self.ends[name] = s
        return s

    def __getitem__(self, name):
        if name in self.plcs:
            return self.plcs[name]
        if name in self.peers:
            return self.peers[name]
        if name in self.ends:
            return self.ends[name]
        raise KitError(f"{name}: no PLC, peer, relay or control system of that name (have: "
                       f"{', '.join(list(self.plcs) + list(self.peers) + list(self.ends)) or 'none'})")

    # ------------------------------------------------------------------ faults

    def lose(self, station, direction, record=None, times=1):
        """Lose the next `times` radio telegrams of `station` that carry a block (direction
        "up": station -> MDP, "down": MDP -> station) whose first register is `record`
        (None: any block)."""
        self._where(station)
        if direction not in ("up", "down"):
            raise KitError(f"direction {direction!r}: up or down")
        self._losses.append([station, direction == "up", record, times])
        if self._fate is None:
            self._fate = S.FATE_FN(self._decide)
            self.lib.mipemu_net_set_fate(self.lib.mipcosim_net(self.sim), self._fate, None)

    def _decide(self, _user, station, up, blk, n):
        for rule in self._losses:
            st, rup, rec, left = rule
            if left > 0 and st == station and bool(up) == rup and (rec is None or (n > 0 and blk[0] == rec)):
                rule[3] -= 1
                self._lost.append((self.now, station, "up" if up else "down",
                                   blk[0] if n > 0 else None))
                return 1
        return 0

    @property
    def lost(self):
        return list(self._lost)

    def restart(self, name, mode="cold", down_s=0.5):
        p = self[name]
        if not isinstance(p, KitPlc):
            raise KitError(f"{name}: only a PLC restarts")
        p.restart(mode, down_s)

    # ------------------------------------------------------------------ running

    def run_for(self, seconds):
        self.run_until_time(self.now + int(seconds * SEC))

    def _tap_slots(self, n):
        if len(self._free_slots) < n:
            raise KitError("more MIP_Receiver instances on the network than the kernel's 64 "
                           "taps watch (two each)")
        got, self._free_slots = self._free_slots[:n], self._free_slots[n:]
        return got

    def _drain(self):
        """Hand what the kernel's taps logged to the PLCs' delivery taps."""
        for slot, _plc, words in self.kernel.read_taps():
            for p in self.plcs.values():
                if p._taps is not None and p._taps.take(slot, words):
                    break

    def run_until_time(self, t_ns):
        from .report import observer
        observer(self)          # the failure report's eyes: the blocks' diagnosis over time
        try:
            self.kernel.run_until(t_ns)
        except KitError:
            for p in self.peers.values():
                if p.error is not None:
                    e, p.error = p.error, None
                    raise KitError(f"peer {p.name} failed: {type(e).__name__}: {e}") from None
            for p in self.ends.values():
                if getattr(p, "error", None) is not None:
                    e, p.error = p.error, None
                    raise KitError(f"{p.name} failed: {type(e).__name__}: {e}") from None
            raise
        for e in self.ends.values():
            if hasattr(e, "check"):
                try:
                    e.check()       # a control-system stand-in's own failure, not the program's
                except Exception as x:  # noqa: BLE001
                    raise KitError(f"{e.name} failed: {type(x).__name__}: {x}") from None
        self._drain()

    def run_until(self, condition, within_s, step_s=0.5):
        """Run until condition() is true (checked every step_s of virtual time) or within_s
        have passed; returns whether it became true (an until.Until: false, it says so)."""
        from .until import Until
        end = self.now + int(within_s * SEC)
        while self.now < end:
            self.run_until_time(min(end, self.now + int(step_s * SEC)))
            if condition():
                return Until(True, within_s, self.now / SEC)
        return Until(False, within_s, self.now / SEC)

    def stats(self, station=1):
        return self.kernel.radio_stats([station])

    # ------------------------------------------------------------------ the report

    def flush_trace(self):
        """Close the trace file (it is complete on disk afterwards; tracing stops)."""
        if not self.kernel.closed and self.trace_path is not None:
            self.lib.mipcosim_trace_file(self.kernel.handle, None)

    def trace_tail(self, lines=40):
        """The last `lines` trace lines that say something: telegrams that carry a block or
        were lost, Modbus writes and rejected requests, station events (empty polls and
        answers and plain reads are left out, as in the diagram)."""
        if self.trace_path is None or not self.trace_path.is_file():
            return []
        keep = collections.deque(maxlen=lines)
        with open(self.trace_path, encoding="utf-8") as f:
            for line in f:
                if ('"regs":0,' in line and '"lost":false' in line) or \
                        ('"fc":3,' in line and '"exc":0' in line):
                    continue
                keep.append(line.rstrip("\n"))
        return list(keep)

    def _last_block_t(self):
        """Virtual time of the last telegram that carried a block (or the end)."""
        last = None
        with open(self.trace_path, encoding="utf-8") as f:
            for line in f:
                if '"ev":"radio"' in line and '"regs":0,' not in line:
                    m = re.match(r'\{"t":(\d+)', line)
                    if m:
                        last = int(m.group(1))
        return last

    def diagram(self, out: Path, station=1, last_s=6.0, title=None, window=None, marks=()):
        """The sequence diagram (docs' seqdiag) of the `last_s` virtual seconds up to the last
        record on the radio (1 s after its telegram), or of window = (from, to) in virtual ns
        (the failure report's: centred on the fault), as SVG into out; None without a trace."""
        from mipdocs import seqdiag as sd
        if self.trace_path is None or not self.trace_path.is_file():
            return None
        if window is not None:
            t_from, t_end = window
            last_s = (t_end - t_from) / SEC
        else:
            last = self._last_block_t()
            t_end = min(self.now, last + SEC) if last is not None else self.now
            t_from = max(0, t_end - int(last_s * SEC))
        events = []
        with open(self.trace_path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                # cheap prefilter: only lines of the window are parsed
                m = re.match(r'\{"t":(\d+)', line)
                if m and int(m.group(1)) < t_from:
                    continue
                if m and int(m.group(1)) > t_end:
                    break
                try:
                    d = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if isinstance(d, dict) and isinstance(d.get("t"), int) and "ev" in d:
                    d["_line"] = n
                    events.append(d)
        rows = sd.rows_from(events, station, t_from, t_end)
        # notes of the failure report (the fault, the blocks' diagnosis): (t, side, text)
        for t, side, text in marks:
            at = next((i for i, r in enumerate(rows) if r[0] > t), len(rows))
            rows.insert(at, (t, "note", {"side": side, "what": "error", "text": text}))
        svg = sd.render(rows, title or f"station {station}, last {last_s:g} s",
                        f"From {self.trace_path.name}, {t_from / SEC:.3f} s .. {t_end / SEC:.3f} s "
                        "of virtual time; empty polls/answers omitted.")
        out = Path(out)
        out.write_text(svg, encoding="utf-8")
        return out

    def close(self):
        for p in self.plcs.values():
            if p.plc is not None:
                p.plc.close()
        self.kernel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def assert_records(records, expected, what="record"):
    """records (payload lists, in order) against expected(n) for n = 1..: an AssertionError
    naming the first record that differs, or the count."""
    for i, got in enumerate(records, 1):
        want = list(expected(i))
        if list(got[:len(want)]) != want:
            raise AssertionError(f"{what} {i}: got {list(got[:len(want)])}, want {want}")
    return len(records)
