"""A radio network in virtual time with the user's soft-PLCs and note-following peers on it.

One model of each thing: the kernel is mipcosim's (libmipcosim.so: the emulator core and the
lockstep loop), the PLCs are plcharness's, the peer is mippeer's; this module only wires the
user's programs and configs to stations, and adds faults and the failure report.
"""
from __future__ import annotations

import collections
import ctypes
import hashlib
import json
import re
from pathlib import Path

from mipcosim import sim as S
from . import capture, delivery
from plcharness import Plc
from plcharness.build import BuildError, build_program

MS = 1_000_000
SEC = 1_000_000_000
RESPONSE_MAX = 300
_SCAN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_uint64)
REALISTIC = {"bitrate": 9600, "slot_gap_ms": 20, "overhead_bytes": 12}
FAST = {"bitrate": 1_000_000, "slot_gap_ms": 1, "overhead_bytes": 12}


class KitError(Exception):
    """A mistake in what the test or scenario asks for; str() is one line."""


class KitWarning(UserWarning):
    """Something the kit does not stop for but says, in one line: stc's portability warnings
    (once per build), a config key the kit does not follow."""


def _warn(line):
    import warnings
    warnings.warn(KitWarning(line), stacklevel=3)


def _duration_ns(v):
    """A plcrt config duration (100ms, 2s, 500us, 10ns; a bare number is ms), or None."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d*)?)\s*(ms|s|us|ns)?\s*", v)
    if not m:
        return None
    return int(float(m.group(1)) * {"ms": MS, "s": SEC, "us": 1000, "ns": 1, None: MS}[m.group(2)])


def _retain_period(path: Path):
    """(line, value, ns) of a plcrt config's [retain] period, or None."""
    section = None
    for n, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if line.startswith("["):
            section = line.strip("[] ").lower()
        elif section == "retain" and "=" in line:
            key, val = (p.strip() for p in line.split("=", 1))
            if key == "period":
                return n, val, _duration_ns(val)
    return None


def _mapped(config: Path) -> set:
    """Every located address a plcrt config maps (a range's whole image)."""
    out = set()
    for _, _, addr, count in _config_addresses(config):
        m = _LOCATED.fullmatch(addr)
        area, size, a = m.group(1).upper(), m.group(2).upper(), int(m.group(3))
        if size == "X" or count == 1:
            out.add(addr.upper())
        else:
            out.update(f"%{area}{size}{a + i}" for i in range(count))
    return out


_LOCATED = re.compile(r"%([IQM])([XBWDL])(\d+)(?:\.(\d+))?", re.I)
_RANGE_KEYS = {"image"}
_SIZE_KEY = "size"


def _config_addresses(path: Path):
    """(line number, key, address, count) of every located address a plcrt config maps:
    count > 1 for a range's image (its size), 1 for handshake bits and words."""
    out = []
    section, size, pending = None, 1, []
    for n, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("["):
            out += [(ln, k, a, size if k in _RANGE_KEYS else 1) for ln, k, a in pending]
            section, size, pending = line, 1, []
            continue
        if "=" not in line:
            continue
        key, val = (p.strip() for p in line.split("=", 1))
        if key == _SIZE_KEY and val.isdigit():
            size = int(val)
        elif _LOCATED.fullmatch(val):
            pending.append((n, key, val.upper()))
    out += [(ln, k, a, size if k in _RANGE_KEYS else 1) for ln, k, a in pending]
    return out


def _declared(build) -> set:
    """The located addresses the program declares (LOCATED_VARIABLES.h of the build)."""
    f = Path(build.outdir) / "gen" / "LOCATED_VARIABLES.h"
    out = set()
    if f.is_file():
        for m in re.finditer(r"__LOCATED_VAR\(\s*\w+\s*,\s*\w+\s*,\s*(\w)\s*,\s*(\w)\s*,\s*(\d+)"
                             r"(?:\s*,\s*(\d+))?", f.read_text()):
            out.add(f"%{m.group(1)}{m.group(2)}{m.group(3)}" + (f".{m.group(4)}" if m.group(4) else ""))
    return out


# diagnostics the runtime writes for whoever wants them (a device's error counter and online
# bit, a range's status word): a program may leave them undeclared
OPTIONAL_OUTPUTS = {"errors", "online", "status"}


def check_config(build, config: Path):
    """One line (KitError) for the first address the config maps that the program does not
    declare: handshake bits and words (trigger, done, error, length, the [retain] request and
    saved) must be declared, of a range's image at least one address; the diagnostics of
    OPTIONAL_OUTPUTS may stay undeclared."""
    declared = _declared(build)
    if not declared and config.suffix == ".cfg":
        return
    for line, key, addr, count in _config_addresses(config):
        if key in OPTIONAL_OUTPUTS:
            continue
        m = _LOCATED.fullmatch(addr)
        area, size, a, b = m.group(1), m.group(2), int(m.group(3)), m.group(4)
        if count > 1 and size != "X":
            if not any(f"%{area}{size}{a + i}" in declared for i in range(count)):
                raise KitError(f"{config}:{line}: error: {key} = {addr} (size {count}): the program "
                               f"declares none of %{area}{size}{a}..%{area}{size}{a + count - 1}")
        elif addr not in declared:
            raise KitError(f"{config}:{line}: error: {key} = {addr}: the program does not declare {addr}")


SEMANTICS = ("matiec", "openplc", "iec")


def build(sources, workdir: Path, compiler="stc", tick_ms=None, semantics=None):
    """The user's ST sources built into a soft-PLC (one line per error: file:line:col).
    compiler: "stc" (the default), "matiec" or "auto" (matiec when iec2c is on PATH);
    semantics: stc's values where IEC 61131-3 leaves them open (None: PLCRT_SEMANTICS, else
    matiec's; "openplc": those of OpenPLC's matiec fork; "iec"). stc's warnings are shown
    once per build (KitWarning)."""
    import os
    from plcharness.build import matiec_available
    if compiler == "auto":
        compiler = "matiec" if matiec_available() else "stc"
    semantics = semantics or os.environ.get("PLCRT_SEMANTICS") or None
    if semantics is not None and semantics not in SEMANTICS:
        raise KitError(f"semantics {semantics!r}: use matiec, openplc or iec")
    srcs = [Path(s) for s in sources]
    for s in srcs:
        if not s.is_file():
            raise KitError(f"{s}: error: no such ST source")
    if srcs and not any(re.search(r"\bCONFIGURATION\b", re.sub(r"\(\*.*?\*\)", " ", s.read_text(
            errors="replace"), flags=re.S), re.I) for s in srcs):
        raise KitError(f"{srcs[-1]}: error: no CONFIGURATION: the kit runs a program from a "
                       "CONFIGURATION whose TASK has an INTERVAL (CONFIGURATION Config0 RESOURCE "
                       "Res0 ON PLC TASK tMain(INTERVAL := T#10ms, PRIORITY := 0); PROGRAM p WITH "
                       "tMain : YourProgram; ...), the last source")
    # the output directory is named by the sources' paths: another program (or the same names
    # elsewhere) gets its own, so a PLC restarted later reloads its own program
    digest = hashlib.sha1("\n".join(str(p.resolve()) for p in srcs).encode()).hexdigest()[:10]
    key = "-".join(p.stem for p in srcs[-2:])[:40] + "-" + digest + (f"-{semantics}" if semantics else "")
    try:
        result = build_program(srcs, Path(workdir) / f"build-{key}-{compiler}", compiler=compiler,
                               semantics=semantics)
        w = Path(result.outdir) / "gen" / "STC_WARNINGS.txt"
        if w.is_file():
            # a cached build's warnings name the sources it was built from: name these
            by_name = {p.name: os.path.normpath(p) for p in srcs}
            for line in w.read_text().splitlines():
                m = re.match(r"(.+?):(\d+:\d+: .*)", line)
                if m and Path(m.group(1)).name in by_name:
                    line = f"{by_name[Path(m.group(1)).name]}:{m.group(2)}"
                _warn(line)
        return result
    except BuildError as e:
        lines = [l for l in str(e).splitlines() if l.strip()]
        located = [l for l in lines if re.match(r".+:\d+:\d+: ", l)]
        first = next((l for l in located if ": error" in l), located[0] if located else
                     (lines[0] if lines else ""))
        raise KitError(first or f"{srcs[-1]}: error: the program does not build") from None


def _ranges(addrs):
    """['%MW0', '%MW1', '%MW3'] as '%MW0..%MW1, %MW3'."""
    out, run = [], []
    for a in addrs:
        if run and int(a[3:]) == int(run[-1][3:]) + 1:
            run.append(a)
            continue
        if run:
            out.append(run[0] if len(run) == 1 else f"{run[0]}..{run[-1]}")
        run = [a]
    if run:
        out.append(run[0] if len(run) == 1 else f"{run[0]}..{run[-1]}")
    return ", ".join(out)


class KitPlc:
    """A user's program on the network: read and write variables and located addresses by
    name (plcharness's names: "MAIN.x", "%QW100"); survives restarts (always the live instance)."""

    def __init__(self, net, name, result, config, at, retain_period_ms):
        self.net, self.name, self.result, self.config, self.at = net, name, result, config, at
        # the snapshot period: the test's, else the config's [retain] period (what plcrt does
        # with it), else 1 s; a test's that differs from the config's is said in one line
        conf = _retain_period(config) if config.suffix != ".cfg" else None
        if retain_period_ms is None:
            self.retain_period_ns = conf[2] if conf and conf[2] else 1000 * MS
        else:
            self.retain_period_ns = int(retain_period_ms * MS)
            if conf and conf[2] is not None and conf[2] != self.retain_period_ns:
                _warn(f"{config}:{conf[0]}: [retain] period = {conf[1]} is not what the kit uses "
                      f"for {name}: it takes snapshots every retain_period_ms = {retain_period_ms:g}")
        self._addresses = None
        self.plc = None
        self.pid = None
        self.restarts = []      # (virtual ns, mode, RETAIN restored)
        self._taps = None       # the delivery taps of the program's receivers (delivery.py)
        self._ends = {}         # device -> connect(KitPlc): a relay or UNICOS stand-in (ends.py)
        self.capture_devices = {}   # device -> its recording transport (capture.py)

    def _start(self, snapshot=None):
        net = self.net
        from .ends import slave_config
        plc = Plc(self.result, net.workdir, config=slave_config(self.config, net.workdir))
        plc.retain_in_memory(self.retain_period_ns)
        if snapshot is not None:
            plc.retain_load(snapshot)
        lib, sim = net.lib, net.sim
        scan = ctypes.cast(plc.library.plcrt_scan, ctypes.c_void_p)
        if self.pid is None:
            self.pid = lib.mipcosim_plc_add(sim, scan, plc.handle, plc.tick_ns)
            net._check(0 if self.pid >= 0 else -1)
        else:
            net._check(lib.mipcosim_plc_replace(sim, self.pid, scan, plc.handle, plc.tick_ns))
        old, self.plc = self.plc, plc
        if old is not None:
            old.close()
        setter = ctypes.cast(plc.library.plcrt_device_set_transport, ctypes.c_void_p)
        ep = 0 if self.at == "mdp" else int(self.at)
        for i in range(plc.library.plcrt_device_count(plc.handle)):
            dev = plc.library.plcrt_device_name(plc.handle, i)
            if dev.decode() in self._ends:
                self._ends[dev.decode()](self)      # the relay or control system (ends.py)
            elif net.capture is not None:
                capture.wire_device(net, self, plc, dev.decode(), ep)
            else:
                net._check(lib.mipcosim_connect_inproc(sim, self.pid, setter, dev, ep))
        if self._taps is None:
            self._taps = delivery.Taps(net, self.pid)
        self._taps.bind(plc, restored=snapshot is not None)

    def _receiver(self, receiver):
        self.net._drain()
        found = self._taps.by_path
        if receiver is None:
            if len(found) != 1:
                raise KitError(f"{self.name}: the program has {len(found)} MIP_Receiver "
                               f"instances ({', '.join(found) or 'none'}): name one")
            return next(iter(found.values()))
        want = receiver.strip().upper()
        hits = [r for p, r in found.items() if p == want or p.endswith("." + want)]
        if len(hits) != 1:
            raise KitError(f"{self.name}: {receiver}: "
                           f"{'no' if not hits else 'more than one'} MIP_Receiver of that name; "
                           f"the program has {', '.join(found) or 'none'}")
        return hits[0]

    @property
    def receivers(self):
        """Paths of the program's MIP_Receiver instances (a MIP_Link's receiving side is its
        inner RCV), found by their outputs."""
        return list(self._taps.by_path)

    def delivered(self, receiver=None):
        """The payloads a MIP_Receiver of the program delivered (xRecordValid), in order, like
        a peer's records: the tap for the integrator's own central, no glue in the program.
        receiver: its path or the end of it ("RCV1"); not needed with one receiver. A record
        without data (an empty 16#FFFF) is not delivered (st_lib/PROTOCOL.md P15); a warm
        restart forgets what the rolled-back instance delivered after its snapshot."""
        return list(self._receiver(receiver).records)

    def transfers_received(self, receiver=None):
        """Transfers that receiver completed (xTransferEnd)."""
        return self._receiver(receiver).transfers

    def _check_located(self, name):
        """A located address the program does not declare (nor the config map) reads 0 and
        writes nowhere: a one-line KitError instead."""
        if not isinstance(name, str) or not name.lstrip().startswith("%"):
            return
        if self._addresses is None:
            declared = _declared(self.result)
            openplc = self.config.suffix == ".cfg"
            self._addresses = (declared, set() if openplc else _mapped(self.config), openplc)
        declared, mapped, openplc = self._addresses
        addr = name.strip().upper()
        if addr in declared or addr in mapped or (openplc and not addr.startswith("%M")):
            return
        m = _LOCATED.fullmatch(addr)
        if m is None:
            return               # the harness says what is wrong with it
        same = sorted((a for a in declared if a[:3] == addr[:3] and "." not in a),
                      key=lambda a: int(a[3:]))
        have = f" (it declares {_ranges(same)})" if same else ""
        raise KitError(f"{self.name}: {name}: the program does not declare {addr}{have}: "
                       "reading it gives 0, writing it reaches nothing")

    def __getitem__(self, name):
        self._check_located(name)
        try:
            return self.plc[name]
        except Exception as e:  # noqa: BLE001 - the harness's own one-line message
            raise KitError(f"{self.name}: {name}: {e}") from None

    def __setitem__(self, name, value):
        self._check_located(name)
        try:
            self.plc[name] = value
        except Exception as e:  # noqa: BLE001
            raise KitError(f"{self.name}: {name}: {e}") from None

    def restart(self, mode="cold", down_s=0.5):
        """cold: a fresh instance (all state lost, RETAIN too); warm: the RETAIN variables of a
        snapshot taken at the stop (plcrt's SIGTERM); kill9: those of the last periodic
        snapshot (plcrt's kill -9: whatever changed since then is lost)."""
        if mode not in ("cold", "warm", "kill9"):
            raise KitError(f"{self.name}: restart mode {mode!r}: use cold, warm or kill9")
        snap = None
        if mode == "warm" and self.plc.retain_count():
            snap = self.plc.retain_save()
        elif mode == "kill9":
            snap = self.plc.retain_last()
        net = self.net
        net._drain()            # what the taps logged of the old instance
        net._check(net.lib.mipcosim_plc_replace(net.sim, self.pid, None, None, 0))
        # (when, mode, whether RETAIN was restored: not without RETAIN variables, nor before
        # the first snapshot; then it is cold)
        self.restarts.append((net.now, mode, snap is not None))
        net.run_for(down_s)
        self._start(snap)


class KitPeer:
    """mippeer's note-following Peer on a modem of the network (stands in for the other side)."""

    def __init__(self, net, name, at, role, records, lenient, layout, drive, period_ms,
                 retransmit_s, request_s, static_registers, unit=1):
        from mippeer.cli import Loop
        from mippeer.modem import Modem
        from mippeer.peer import Peer
        self.net, self.name, self.at = net, name, at
        ep = 0 if at == "mdp" else int(at)
        unit = unit if at == "mdp" else 1
        lib, sim = net.lib, net.sim
        rsp = ctypes.create_string_buffer(RESPONSE_MAX)

        def transact(adu):
            n = lib.mipcosim_request(sim, ep, adu, len(adu), rsp, len(rsp))
            if n < 0:
                raise S.CosimError(lib.mipcosim_errmsg(sim).decode())
            return rsp.raw[:n]

        try:
            peer = Peer(role, records, layout=layout, drive=drive, lenient=lenient,
                        retransmit_s=retransmit_s, request_s=request_s,
                        static_registers=static_registers)
        except ValueError as e:
            raise KitError(f"peer {name}: {e}") from None
        if net.capture is not None:
            transact = capture.recording(net, name, ep, transact)
        modem = Modem.in_process(transact, "mdp" if at == "mdp" else "trm", unit=unit)
        modem.connect()
        self.peer = peer
        self.loop = Loop(peer, modem)
        self.error = None
        self._t0 = net.now
        self._scan = _SCAN(self._round)
        self.pid = lib.mipcosim_plc_add(sim, ctypes.cast(self._scan, ctypes.c_void_p), 1,
                                        int(period_ms * MS))
        net._check(0 if self.pid >= 0 else -1)

    def _round(self, _rt, _n):
        try:
            self.loop.round((self.net.now - self._t0) / SEC)
            return 0
        except BaseException as e:  # noqa: BLE001 - handed back through the C loop
            self.error = e
            return -1

    @property
    def records(self):
        """Payloads of every record with data the peer accepted, in order (all transfers). An
        empty record (the 16#FFFF a sender writes after a last chunk that came without
        xChunkLast) ends its transfer but is no record: as MIP_Receiver, which does not deliver
        it (st_lib/PROTOCOL.md P15)."""
        r = self.peer.receiver
        if r is None:
            return []
        return [p for t in r.transfers for p in t if p] + [p for p in r.current if p]

    @property
    def transfers(self):
        r = self.peer.receiver
        return len(r.transfers) if r else 0

    @property
    def done(self):
        return self.peer.done


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
        self.lib = S.kernel_lib()
        lib = self.lib
        lib.mipcosim_request.restype = ctypes.c_long
        lib.mipcosim_request.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p,
                                         ctypes.c_size_t, ctypes.c_void_p, ctypes.c_size_t]
        err = ctypes.create_string_buffer(256)
        self._handle = lib.mipcosim_new_args(stations, 1 if static else 0, static_registers,
                                             loss_down, loss_up, burst, seed,
                                             self.radio["bitrate"],
                                             int(self.radio["slot_gap_ms"] * MS),
                                             self.radio["overhead_bytes"], err, len(err))
        if not self._handle:
            raise KitError(err.value.decode())
        self.trace_path = self.workdir / "emulator-trace.jsonl" if trace else None
        # the Modbus traffic; a failure's pcapng holds capture_s seconds of it (capture.py)
        self.capture = capture.ModbusCapture(capture_s) if capture_s else None
        if trace:
            self._check(lib.mipcosim_trace_file(self._handle, str(self.trace_path).encode()))
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
        if self._handle is None:
            raise KitError("the network is closed")
        return self._handle

    @property
    def now(self):
        return self._end if self._handle is None else self.lib.mipcosim_now(self._handle)

    def _check(self, rc):
        if rc != 0:
            raise KitError(self.lib.mipcosim_errmsg(self.sim).decode())

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
        for slot, _plc, words in S.read_taps(self.lib, self.sim):
            for p in self.plcs.values():
                if p._taps is not None and p._taps.take(slot, words):
                    break

    def run_until_time(self, t_ns):
        from .report import observer
        observer(self)          # the failure report's eyes: the blocks' diagnosis over time
        if self.lib.mipcosim_run(self.sim, t_ns) != 0:
            msg = self.lib.mipcosim_errmsg(self.sim).decode()
            for p in self.peers.values():
                if p.error is not None:
                    e, p.error = p.error, None
                    raise KitError(f"peer {p.name} failed: {type(e).__name__}: {e}") from None
            for p in self.ends.values():
                if getattr(p, "error", None) is not None:
                    e, p.error = p.error, None
                    raise KitError(f"{p.name} failed: {type(e).__name__}: {e}") from None
            failed = self.lib.mipcosim_failed_plc(self.sim)
            for p in self.plcs.values():
                if p.pid == failed:
                    why = p.plc.library.plcrt_errmsg(p.plc.handle) or b""
                    msg += f": {p.name}: {why.decode()}"
            raise KitError(msg)
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
        return S.radio_stats(self.lib, self.sim, [station])

    # ------------------------------------------------------------------ the report

    def flush_trace(self):
        """Close the trace file (it is complete on disk afterwards; tracing stops)."""
        if self._handle is not None and self.trace_path is not None:
            self.lib.mipcosim_trace_file(self._handle, None)

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
        from . import _seqdiag_mod
        sd = _seqdiag_mod()
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
        if self._handle is not None:
            self._end = self.lib.mipcosim_now(self._handle)
            self.lib.mipcosim_free(self._handle)
            self._handle = None

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
