"""Co-simulation driver: the example programs (plc/) as soft-PLCs and the emulator core, in one
process, in lockstep virtual time (cosim/README.md)."""
from __future__ import annotations

import ctypes
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from plcharness import Plc, PlcError
from plcharness.build import build_program

from . import layout as L

REPO = L.REPO
LIBDIR = REPO / "build" / "cosim"
if (Path(__file__).resolve().parent / "_lib" / "libmipcosim.so").is_file():
    LIBDIR = Path(__file__).resolve().parent / "_lib"     # installed by the test kit (kit/)
MS = 1_000_000
SEC = 1_000_000_000


class CosimError(RuntimeError):
    pass


# the emulator core's scripted-fault hook (mipemu.h: mipemu_fate_fn)
FATE_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                           ctypes.POINTER(ctypes.c_uint16), ctypes.c_int)


class Stats(ctypes.Structure):
    """mipemu_stats: one station's radio counters."""
    _fields_ = [(n, ctypes.c_uint64) for n in (
        "polls", "tel_down", "lost_down", "tel_up", "lost_up", "blocks_down", "blocks_up",
        "dup_down", "dup_up", "confirmed_down", "confirmed_up")]


_LIB = None


def kernel_lib():
    """libmipcosim.so with the argument types of the kernel's API (mipcosim.h) and of the
    emulator core's that it exports (mipemu.h); loaded once. The one binding: the chains here,
    the docs' tools, the bench and the st_lib test bench use it."""
    global _LIB
    if _LIB is not None:
        return _LIB
    path = LIBDIR / "libmipcosim.so"
    if not path.is_file():
        raise CosimError(f"{path} missing: run `make build/cosim/libmipcosim.so`")
    lib = ctypes.CDLL(str(path))
    c = ctypes
    u16p = c.POINTER(c.c_uint16)
    for name, res, args in [
        ("mipcosim_new_args", c.c_void_p, [c.c_int, c.c_int, c.c_int, c.c_double, c.c_double,
                                           c.c_double, c.c_uint64, c.c_uint32, c.c_uint64,
                                           c.c_int, c.c_char_p, c.c_size_t]),
        ("mipcosim_free", None, [c.c_void_p]),
        ("mipcosim_errmsg", c.c_char_p, [c.c_void_p]),
        ("mipcosim_net", c.c_void_p, [c.c_void_p]),
        ("mipcosim_now", c.c_uint64, [c.c_void_p]),
        ("mipcosim_plc_add", c.c_int, [c.c_void_p, c.c_void_p, c.c_void_p, c.c_uint64]),
        ("mipcosim_plc_replace", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_void_p, c.c_uint64]),
        ("mipcosim_connect", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_connect_tcp", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_connect_inproc", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_tap", c.c_int, [c.c_void_p, c.c_int, c.c_int, c.c_void_p, c.c_void_p, c.c_int,
                                   c.c_int, c.c_void_p, c.c_int]),
        ("mipcosim_tap_fields", c.c_int, [c.c_void_p, c.c_int, c.c_int, c.c_void_p, c.c_void_p,
                                          c.c_int, c.c_int, c.c_void_p, c.c_int]),
        ("mipcosim_untap", None, [c.c_void_p, c.c_int]),
        ("mipcosim_tap_read", c.c_size_t, [c.c_void_p, c.c_void_p, c.c_size_t]),
        ("mipcosim_run", c.c_int, [c.c_void_p, c.c_uint64]),
        ("mipcosim_failed_plc", c.c_int, [c.c_void_p]),
        ("mipcosim_requests", c.c_uint64, [c.c_void_p]),
        ("mipcosim_scans", c.c_uint64, [c.c_void_p]),
        ("mipcosim_trace_file", c.c_int, [c.c_void_p, c.c_char_p]),
        # the emulator core, for a caller that drives the network itself (tests/st_lib)
        ("mipemu_net_stats", c.c_int, [c.c_void_p, c.c_int, c.c_void_p]),
        ("mipemu_net_advance", c.c_int, [c.c_void_p, c.c_uint64]),
        ("mipemu_handle", c.c_long, [c.c_void_p, c.c_int, c.c_char_p, c.c_size_t,
                                     c.c_char_p, c.c_size_t]),
        ("mipemu_net_set_fate", None, [c.c_void_p, FATE_FN, c.c_void_p]),
        ("mipemu_net_inject", c.c_int, [c.c_void_p, c.c_int, c.c_int, u16p, c.c_int]),
        ("mipemu_net_peek", c.c_int, [c.c_void_p, c.c_int, c.c_int, c.c_uint, c.c_uint, u16p]),
        # SIPROTEC relays in the kernel's virtual time (issue 35; mipcosim.relay wraps them)
        ("mipcosim_relay_add", c.c_int, [c.c_void_p, c.c_void_p]),
        ("mipcosim_relay_restart", c.c_int, [c.c_void_p, c.c_int, c.c_void_p]),
        ("mipcosim_relay", c.c_void_p, [c.c_void_p, c.c_int]),
        ("mipcosim_connect_relay", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_relay_request", c.c_long, [c.c_void_p, c.c_int, c.c_char_p, c.c_size_t,
                                              c.c_char_p, c.c_size_t]),
        ("siprotec_config_default", None, [c.c_void_p]),
        ("siprotec_script", c.c_int, [c.c_void_p, c.c_uint64, u16p]),
        ("siprotec_next_event", c.c_uint64, [c.c_void_p]),
        ("siprotec_peek", None, [c.c_void_p, c.c_uint16, c.c_uint, u16p]),
        ("siprotec_get_stats", None, [c.c_void_p, c.c_void_p]),
    ]:
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    _LIB = lib
    return lib


_lib = kernel_lib          # (the name the modules here and the docs' tools use)
_Stats = Stats


_BUILDS = {}


def read_taps(lib, sim):
    """The entries the kernel's taps logged since the last call, oldest first: (tap slot, PLC
    id, words) (mipcosim_tap_read's [tap, plc, n, words...])."""
    buf = (ctypes.c_uint16 * 65536)()
    while True:
        n = lib.mipcosim_tap_read(sim, buf, len(buf))
        if n == 0:
            return
        i = 0
        while i < n:
            k = buf[i + 2]
            yield buf[i], buf[i + 1], list(buf[i + 3:i + 3 + k])
            i += 3 + k


def radio_stats(lib, sim, stations):
    """The emulator's radio counters summed over `stations`, and the kernel's scans and
    Modbus requests."""
    tot = {}
    for s in stations:
        st = _Stats()
        lib.mipemu_net_stats(lib.mipcosim_net(sim), s, ctypes.byref(st))
        for name, _ in _Stats._fields_:
            tot[name] = tot.get(name, 0) + getattr(st, name)
    tot["requests"] = lib.mipcosim_requests(sim)
    tot["scans"] = lib.mipcosim_scans(sim)
    return tot


def build(role, bidi, workdir: Path, compiler="stc", tick_ms=10, sources=None):
    """The example program of `role`, its task interval (the scan tick) tick_ms; sources: other
    ST files instead (the last one holds the CONFIGURATION), e.g. a test's variant."""
    key = (role, bidi, compiler, tick_ms, tuple(map(str, sources or ())))
    if key not in _BUILDS:
        tag = f"{role}{'-bidi' if bidi else ''}-{compiler}" + (f"-{tick_ms}ms" if tick_ms != 10 else "")
        if sources:
            tag += "-" + hashlib.sha1("\n".join(key[4]).encode()).hexdigest()[:10]
        out = Path(workdir) / f"build-{tag}"
        srcs = [str(f) for f in sources] if sources else L.program_sources(role, bidi)
        if tick_ms != 10:
            # the same program with another task interval: the PLC's clock (timers, timeouts)
            # goes on by one interval per scan, so it must be the kernel's scan tick
            main = Path(srcs[-1])
            text = main.read_text()
            if text.count("INTERVAL := T#10ms") != 1:
                raise CosimError(f"{main}: no single 'INTERVAL := T#10ms' to set the scan tick")
            src_dir = Path(workdir) / f"src-{tag}"  # not in out: the build replaces only its own output
            src_dir.mkdir(parents=True, exist_ok=True)
            copy = src_dir / main.name
            copy.write_text(text.replace("INTERVAL := T#10ms", f"INTERVAL := T#{tick_ms}ms"))
            srcs = srcs[:-1] + [str(copy)]
        _BUILDS[key] = build_program(srcs, out, compiler=compiler)
    return _BUILDS[key]


@dataclass
class Event:
    t: int
    tap: int
    plc: int
    words: list


@dataclass
class Radio:
    """Radio parameters of the emulator network."""
    bitrate: int = 1_000_000        # fast: a slot of a few ms
    slot_gap_ns: int = 1 * MS
    overhead_bytes: int = 12

    @classmethod
    def realistic(cls):
        return cls(9600, 20 * MS, 12)


@dataclass
class Setup:
    stations: int = 1
    static: bool = False
    static_registers: int = 123
    polled: bool = False
    bidi: bool = False
    loss: float = 0.0
    burst: float = 0.0
    seed: int = 1
    records: int = 5
    per_transfer: int = 0
    payload: int = 16
    timeout_ms: int = 300
    log_period_ms: int = 0
    transfer_timeout_s: int = 0
    radio: Radio = field(default_factory=Radio)
    compiler: str = "stc"
    # the PLC-to-modem link: 0 = Modbus TCP (free), else Modbus RTU at this baud rate (8E1): the
    # runtime's devices are serial, and in virtual time each exchange takes its time on the line
    # (runtime_shim: "serial line in virtual time"; docs/serial.md); with transport "inproc"
    link_baud: int = 0
    # the read ranges read the MIP status word first (status_first): True the status and count
    # alone until bit 0 shows new data; a number n: the first read takes n registers (3,
    # L.RTU_STATUS_FIRST: an acknowledgement of one register comes with the status)
    status_first: bool | int = False
    # a read and a write of a device pending together go as one FC23 (device option fc23)
    fc23: bool = False
    # "inproc": the runtime hands each request ADU to the emulator core (the kernel);
    # "socketpair" / "tcp": the same ADUs through libmodbus over a socketpair / a TCP
    # connection on 127.0.0.1
    transport: str = "inproc"
    tick_ms: int = 10          # scan tick = the programs' task interval
    # RETAIN snapshots, in memory, where plcrt would save them: every retain_period_ms of scan
    # time (0: only on request) and whenever a program sets [retain] request (L.RETAIN_REQUEST)
    retain_period_ms: int = 1000
    # the blocks' xRetained (st_lib/PROTOCOL.md W1, W2, W4: durable before visible), for warm
    # restarts without loss or duplicate, in both layouts (MIP_Link: W4)
    retain: bool = False
    # MIP_Sender's uWindow (st_lib/PROTOCOL.md P27): 2 pipelines the records of a transfer
    window: int = 1
    # role ("outstation" / "central") -> ST files replacing the example program (tests)
    sources: dict = field(default_factory=dict)
    # station 1's ranges are the vendor stand-ins' request channel (mipcosim/glue.py): True for
    # both sides, or the roles ("outstation", "central") whose program has the glue
    channel: bool | tuple = False

    def channel_of(self, role):
        return self.channel is True or role in (self.channel or ())

    def params(self, station, session, start=0):
        down = (0, 0, 0, 0)
        if isinstance(start, dict):       # the central: one start per station
            down = tuple(start.get(s, 0) for s in range(1, 5))
            start = 0
        return L.Params(start=start, down_start=down, records=self.records, per_transfer=self.per_transfer,
                        payload=self.payload, session=session, station=station,
                        polled=self.polled, static=self.static, retain=self.retain,
                        window=self.window,
                        log_period_ms=self.log_period_ms, timeout_ms=self.timeout_ms,
                        chunk=self.static_registers if self.static else 123,
                        transfer_timeout_s=self.transfer_timeout_s)


TICK_NS = 10 * MS
RESTART = -1
WARM = -2     # a warm restart: words = [tap, restored seq, ...] of the PLC's taps


class _Kernel:
    """What Chain and Network share: the kernel (self.lib, self.sim) and their PLCs
    (self.plcs), virtual time, closing."""

    _handle = None          # the C kernel; None before it exists and after close()
    _end_ns = 0             # virtual time at close()

    @property
    def sim(self):
        if self._handle is None:
            raise CosimError("the co-simulation is closed")
        return self._handle

    @sim.setter
    def sim(self, handle):
        self._handle = handle

    @property
    def now(self):
        """Virtual time in ns; after close() the time it was closed at."""
        if self._handle is None:
            return self._end_ns
        return self.lib.mipcosim_now(self._handle)

    def close(self):
        for plc in self.plcs.values():
            plc.close()
        self.plcs = {}
        if self._handle:
            self._end_ns = self.lib.mipcosim_now(self._handle)
            self.lib.mipcosim_free(self._handle)
            self._handle = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Chain(_Kernel):
    """Outstation PLC(s) + central PLC + emulator network in one process."""

    def __init__(self, setup: Setup, workdir: Path, trace=None):
        if not 1 <= setup.stations <= L.MAX_STATIONS:
            raise CosimError(f"stations {setup.stations}: the central program (plc/central.st) "
                             f"serves 1..{L.MAX_STATIONS}")
        if not 1 <= setup.tick_ms <= 1000:
            raise CosimError(f"tick_ms {setup.tick_ms}: use 1..1000")
        self.s = setup
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.lib = _lib()
        err = ctypes.create_string_buffer(256)
        self.sim = self.lib.mipcosim_new_args(
            setup.stations, 1 if setup.static else 0, setup.static_registers, setup.loss,
            setup.loss, setup.burst, setup.seed, setup.radio.bitrate, setup.radio.slot_gap_ns,
            setup.radio.overhead_bytes, err, len(err))
        if not self._handle:
            raise CosimError(err.value.decode())
        if trace:
            self._check(self.lib.mipcosim_trace_file(self.sim, str(trace).encode()))
        self.tick_ns = setup.tick_ms * MS
        self.out_build = build("outstation", setup.bidi, self.workdir, setup.compiler, setup.tick_ms,
                               setup.sources.get("outstation"))
        self.cen_build = build("central", setup.bidi, self.workdir, setup.compiler, setup.tick_ms,
                               setup.sources.get("central"))
        # the [retain] sections give the period and the handshake addresses; their files are
        # never written: the kernel keeps each PLC's snapshots in memory
        if setup.link_baud and setup.transport != "inproc":
            raise CosimError(f"link rtu:{setup.link_baud} needs the inproc transport "
                             f"(the emulator's socket fronts of the kernel speak TCP framing)")
        # an RTU link: the serial line is never opened (the transport is in process); its
        # settings give the time each exchange takes on it
        ser = (lambda name: L.serial_keys(f"cosim-{name}", setup.link_baud)) if setup.link_baud \
            else (lambda name: None)
        self.out_conf = self.workdir / "outstation.conf"
        self.out_conf.write_text(L.outstation_config(15021, retain=L.retain_section(
            self.workdir / "outstation.retain", setup.retain_period_ms), serial=ser("trm"),
            status_first=setup.status_first, fc23=setup.fc23,
            channel=setup.channel_of("outstation")))
        self.cen_conf = self.workdir / "central.conf"
        self.cen_conf.write_text(L.central_config(15020, setup.stations, retain=L.retain_section(
            self.workdir / "central.retain", setup.retain_period_ms), serial=ser("mdp"),
            status_first=setup.status_first, fc23=setup.fc23,
            channel=setup.channel_of("central")))
        self.events: list[Event] = []
        self.boots = {("out", s): 0 for s in range(1, setup.stations + 1)}
        self.boots[("cen", 0)] = 0
        self.plcs = {}       # ("out", s) / ("cen", 0) -> Plc
        self.ids = {}
        self.restarts = []   # (t, which)
        self.sessions = {}   # ("out", s) -> [sessions], ("cen", 0) -> [sessions]
        self.warm_restarts = 0       # restart(..., warm=True) calls (retain_stats)
        self.warm = []               # (t, which, graceful) of the warm restarts that restored
        self.last_snapshot = {}      # who -> the last snapshot any instance of it took
        self._taps_of = {}           # who -> [(tap slot, seq address name)]
        self._snapshots_before = 0   # snapshots of PLC instances that are gone
        for s in range(1, setup.stations + 1):
            self._start(("out", s))
        self._start(("cen", 0))

    # ------------------------------------------------------------------ wiring

    def _check(self, rc):
        if rc != 0:
            raise CosimError(self.lib.mipcosim_errmsg(self.sim).decode())

    def session(self, who):
        return 1 + self.boots[who]

    def _start(self, who, start=None, snapshot=None, warm=False):
        role, s = who
        plc = Plc(self.out_build if role == "out" else self.cen_build, self.workdir,
                  config=self.out_conf if role == "out" else self.cen_conf)
        if plc.tick_ns != self.tick_ns:
            raise CosimError(f"{who}: the program scans every {plc.tick_ns} ns, the kernel every {self.tick_ns}")
        plc.retain_in_memory(self.s.retain_period_ms * MS)
        if snapshot is not None:              # a warm restart (restart() checked it applies)
            plc.retain_load(snapshot)         # after config_init__, before the first scan
        old = self.plcs.get(who)
        self.plcs[who] = plc
        scan = ctypes.cast(plc.library.plcrt_scan, ctypes.c_void_p)
        if self.s.transport == "inproc":
            set_fd = ctypes.cast(plc.library.plcrt_device_set_transport, ctypes.c_void_p)
            connect = self.lib.mipcosim_connect_inproc
        elif self.s.transport in ("socketpair", "tcp"):
            set_fd = ctypes.cast(plc.library.plcrt_device_set_fd, ctypes.c_void_p)
            connect = (self.lib.mipcosim_connect if self.s.transport == "socketpair"
                       else self.lib.mipcosim_connect_tcp)
        else:
            raise CosimError(f"transport {self.s.transport!r}: use inproc, socketpair or tcp")
        if who in self.ids:
            self._check(self.lib.mipcosim_plc_replace(self.sim, self.ids[who], scan, plc.handle, self.tick_ns))
        else:
            pid = self.lib.mipcosim_plc_add(self.sim, scan, plc.handle, self.tick_ns)
            self._check(0 if pid >= 0 else -1)
            self.ids[who] = pid
        if old is not None:
            self._snapshots_before += old.retain_saves
            old.close()
        pid = self.ids[who]
        if role == "out":
            self._check(connect(self.sim, pid, set_fd, b"trm", s))
        else:
            for st in range(1, self.s.stations + 1):
                self._check(connect(self.sim, pid, set_fd, f"mdp{st}".encode(), 0))
        if start is None:
            start = 0 if role == "out" else {}
        session = self.session(who)
        if not warm:
            self.sessions.setdefault(who, []).append((session, start))
        params = self.s.params(s if role == "out" else 0, session, start)
        for i, w in enumerate(params.words()):
            plc[f"%MW{i}"] = w
        self._taps(who, warm)

    def _addr(self, plc, name):
        return plc.address(name)

    def _taps(self, who, warm=False):
        role, s = who
        plc, pid = self.plcs[who], self.ids[who]
        bidi = self.s.bidi
        prog = ("OUTSTATIONBIDI" if bidi else "OUTSTATION") if role == "out" else \
            ("CENTRALBIDI" if bidi else "CENTRAL")
        self._taps_of[who] = []

        def tap(slot, base, nhdr, data_path=None, seq_src=None):
            self._taps_of[who].append((slot, base))
            if warm and seq_src:
                # the %MW mirror of the event counter is written by the first scan: a restored
                # counter is put there now, so the tap does not take the restore for an event
                plc[f"%MW{base}"] = plc[f"{prog}.{seq_src}.WSEQ"]
            seq = self._addr(plc, f"%MW{base}")
            hdr = self._addr(plc, f"%MW{base + 1}")
            data = self._addr(plc, data_path) if data_path else None
            # the %MW words are contiguous in the image
            self._check(self.lib.mipcosim_tap(self.sim, slot, pid, seq, hdr, nhdr,
                                              2 if data else -1, data, 122))

        if role == "out":
            b = L.peer_base(1)
            tap(20 + s, b + L.S_SEQ, 2, seq_src="SRC")         # sender events: flags, error
            if bidi:
                tap(30 + s, b + L.R_SEQ, 4, "OUTSTATIONBIDI.LINK.ARECORD", "STORE")
        else:
            for st in range(1, self.s.stations + 1):
                b = L.peer_base(st)
                fb = f"CENTRALBIDI.LINK{st}" if bidi else f"CENTRAL.RCV{st}"
                tap(st, b + L.R_SEQ, 4, f"{fb}.ARECORD", f"STORE{st}")   # flags, number, len, error
                if bidi:
                    tap(10 + st, b + L.S_SEQ, 2, seq_src=f"SRC{st}")

    # ------------------------------------------------------------------ running

    def run_until(self, t_ns):
        rc = self.lib.mipcosim_run(self.sim, t_ns)
        self._drain()
        if rc != 0:
            msg = self.lib.mipcosim_errmsg(self.sim).decode()
            failed = self.lib.mipcosim_failed_plc(self.sim)
            for who, pid in self.ids.items():
                if pid == failed:
                    plc = self.plcs[who]
                    why = plc.library.plcrt_errmsg(plc.handle) or b""
                    msg += f": {who}: {why.decode()}"
            raise CosimError(msg)

    def run_for(self, ns):
        self.run_until(self.now + ns)

    def _drain(self):
        t = self.now
        for tap, plc, words in read_taps(self.lib, self.sim):
            self.events.append(Event(t, tap, plc, words))

    def restart(self, who, down_ns=500 * MS, warm=False, graceful=False):
        """A PLC restart: off for down_ns (its modem keeps running), then a fresh instance of
        the program. Cold (default): all state lost, the next session number. warm: the fresh
        instance gets the RETAIN variables of the last complete snapshot the PLC took (plcrt's
        kill -9 semantics: everything since that snapshot is lost; an instance that took none
        gets the one its predecessor restored) and goes on in the same session; graceful: a
        snapshot is taken at the stop (plcrt's SIGTERM), so nothing is lost. A program without
        RETAIN variables, or with no snapshot yet, starts cold."""
        pid = self.ids[who]
        snapshot = None
        if warm:
            old = self.plcs[who]
            snapshot = (old.retain_save() if graceful and old.retain_count() else
                        old.retain_last() or self.last_snapshot.get(who))
        self.warm_restarts += 1 if warm else 0
        if snapshot and self.plcs[who].retain_count() > 0:
            self.last_snapshot[who] = snapshot
            self._check(self.lib.mipcosim_plc_replace(self.sim, pid, None, None, 0))
            self.warm.append((self.now, who, graceful))
            self.run_for(down_ns)
            self._start(who, None, snapshot, warm=True)
            marker = []
            for slot, base in self._taps_of[who]:
                marker += [slot, self.mw(who, base)]
            self.events.append(Event(self.now, WARM, pid, marker))   # for the checker
            return
        # a logger keeps its data and read-out pointer (retained memory): the restarted
        # program resumes there, in a new session
        if who[0] == "out":
            b = L.peer_base(1)
            start = self.mw(who, b + L.S_OUT_LO) + (self.mw(who, b + L.S_OUT_HI) << 16)
        else:
            start = {}
            for s in range(1, self.s.stations + 1):
                b = L.peer_base(s)
                start[s] = self.mw(who, b + L.S_OUT_LO) + (self.mw(who, b + L.S_OUT_HI) << 16)
        self._check(self.lib.mipcosim_plc_replace(self.sim, pid, None, None, 0))
        self.restarts.append((self.now, who))
        self.events.append(Event(self.now, RESTART, pid, []))   # marker for the checker
        self.run_for(down_ns)
        self.boots[who] += 1
        self._start(who, start)

    def retain_stats(self):
        """{"snapshots": RETAIN snapshots taken by all PLCs (all their restarts included),
        "warm_restarts": warm restarts, "restored": those that restored a snapshot (the others
        were cold: no RETAIN variables, or no snapshot yet)}."""
        return {"snapshots": self._snapshots_before + sum(p.retain_saves for p in self.plcs.values()),
                "warm_restarts": self.warm_restarts, "restored": len(self.warm)}

    def sender_windows(self):
        """{1, 2}: the windows the senders of the running PLCs run (MIP_Sender's xPipe: uWindow
        2 applies only where P27 allows it, e.g. not in MIP_Link)."""
        out = set()
        for (role, _), plc in self.plcs.items():
            names = (["OUT0.LINK.SND.XPIPE"] if self.s.bidi else ["OUT0.SND.XPIPE"]) if role == "out" \
                else ([f"CEN0.LINK{st}.SND.XPIPE" for st in range(1, self.s.stations + 1)]
                      if self.s.bidi else [])
            for n in names:
                try:
                    out.add(2 if plc[n] else 1)
                except PlcError:      # a test's own program (Setup.sources) without that sender
                    pass
        return out

    def mw(self, who, addr):
        return self.plcs[who][f"%MW{addr}"]

    def finished(self):
        """Every sender read out all its records and no transfer is open at a receiver."""
        for s in range(1, self.s.stations + 1):
            if self.mw(("out", s), L.peer_base(1) + L.S_ALL) != 1:
                return False
            if self.s.bidi and self.mw(("cen", 0), L.peer_base(s) + L.S_ALL) != 1:
                return False
        return True

    def run_to_end(self, limit_ns, step_ns=SEC, settle_ns=3 * SEC):
        """Run until finished() (then settle_ns more, so late duplicates show) or limit_ns."""
        while self.now < limit_ns:
            self.run_for(step_ns)
            if self.finished():
                self.run_for(settle_ns)
                return True
        return False

    def radio_stats(self):
        return radio_stats(self.lib, self.sim, range(1, self.s.stations + 1))


class Network(_Kernel):
    """The largest MIP network: `stations` outstation soft-PLCs (plc/outstation.st, one per
    TRM-810) and ONE central program for all of them (mipprograms.logger.central_many(n):
    n receivers behind one shared Modbus client) on one MDP-810, in lockstep virtual time.
    Stations per central and the scan tick are parameters. Delivery is checked per station
    from the central's record stores: registers committed and their Fletcher sums against
    what each logger wrote (check()); Chain's per-event taps need a %MW block per station,
    which 247 stations do not have."""

    def __init__(self, stations, workdir: Path, *, records=5, per_transfer=0, payload=16,
                 loss=0.0, seed=1, radio=None, tick_ms=100, timeout_ms=2000, compiler="stc",
                 transfer_timeout_s=0, window=1):
        if not 1 <= stations <= 247:
            raise CosimError(f"stations {stations}: one MDP-810 serves unit ids 1..247")
        if not 1 <= tick_ms <= 1000:
            raise CosimError(f"tick_ms {tick_ms}: use 1..1000")
        self.n = stations
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.tick_ns = tick_ms * MS
        self.params = L.Params(records=records, per_transfer=per_transfer, payload=payload,
                               timeout_ms=timeout_ms, transfer_timeout_s=transfer_timeout_s,
                               window=window)
        self.lib = _lib()
        radio = radio or Radio.realistic()
        err = ctypes.create_string_buffer(256)
        self.sim = self.lib.mipcosim_new_args(stations, 0, 123, loss, loss, 0.0, seed,
                                              radio.bitrate, radio.slot_gap_ns,
                                              radio.overhead_bytes, err, len(err))
        if not self._handle:
            raise CosimError(err.value.decode())
        self.plcs = {}
        try:
            from mipprograms.logger import central_many
            src = self.workdir / f"src-many-{stations}" / "central_many.st"
            src.parent.mkdir(parents=True, exist_ok=True)
            text = central_many(stations)
            if not src.is_file() or src.read_text() != text:
                src.write_text(text)
            lib_src = [str(L.ST_LIB / f) for f in L.LIB_FILES] + [str(L.PLC_DIR / "PLC_Logger.st")]
            out_b = build("outstation", False, self.workdir, compiler, tick_ms)
            cen_b = build("central_many", False, self.workdir, compiler, tick_ms,
                          lib_src + [str(src)])
            oconf = self.workdir / "outstation.conf"
            oconf.write_text(L.outstation_config(15021))
            cconf = self.workdir / "central_many.conf"
            cconf.write_text(L.central_many_config(15020))
            for s in range(1, stations + 1):
                self._add(("out", s), out_b, oconf, [("trm", s)],
                          L.Params(**{**self.params.__dict__, "station": s}))
            self._add(("cen", 0), cen_b, cconf, [("mdp", 0), ("mdp_ack", 0)],
                      L.Params(**{**self.params.__dict__, "station": 0}))
        except BaseException:
            self.close()
            raise

    def _add(self, who, build_result, conf, wires, params):
        plc = Plc(build_result, self.workdir, config=conf)
        self.plcs[who] = plc
        if plc.tick_ns != self.tick_ns:
            raise CosimError(f"{who}: the program scans every {plc.tick_ns} ns, the kernel every {self.tick_ns}")
        pid = self.lib.mipcosim_plc_add(self.sim, ctypes.cast(plc.library.plcrt_scan, ctypes.c_void_p),
                                        plc.handle, self.tick_ns)
        if pid < 0:
            raise CosimError(self.lib.mipcosim_errmsg(self.sim).decode())
        setter = ctypes.cast(plc.library.plcrt_device_set_transport, ctypes.c_void_p)
        for dev, ep in wires:
            if self.lib.mipcosim_connect_inproc(self.sim, pid, setter, dev.encode(), ep) != 0:
                raise CosimError(self.lib.mipcosim_errmsg(self.sim).decode())
        for i, w in enumerate(params.words()):
            plc[f"%MW{i}"] = w

    def run_for(self, ns):
        if self.lib.mipcosim_run(self.sim, self.now + ns) != 0:
            raise CosimError(self.lib.mipcosim_errmsg(self.sim).decode())

    def central(self, addr):
        """%MW addr of the central (layout M_*: its shared client's statistics)."""
        return self.plcs[("cen", 0)][f"%MW{addr}"]

    def station(self, s):
        """What the central holds of station s: {"committed", "sum", "transfers", "failed",
        "records"} from its PLC_RecordStore; and whether the outstation read out all."""
        cen = self.plcs[("cen", 0)]
        p = f"CEN0.STORE{s}."
        return {"committed": cen[p + "UDICOMMITTED"], "sum": (cen[p + "WSUMA"], cen[p + "WSUMB"]),
                "transfers": cen[p + "UTRANSFERS"], "failed": cen[p + "UFAILED"],
                "records": cen[p + "UDIRECORDS"],
                "all_out": self.plcs[("out", s)][f"%MW{L.peer_base(1) + L.S_ALL}"] == 1}

    def read_out(self, s):
        """Outstation s has read out all its records (every transfer acknowledged)."""
        return self.plcs[("out", s)][f"%MW{L.peer_base(1) + L.S_ALL}"] == 1

    def finished(self):
        return all(self.read_out(s) for s in range(1, self.n + 1))

    def check(self):
        """Problems (one line each) of the delivery: every station's registers committed once,
        in order (the Fletcher sums of all its logger's records), no failed transfer."""
        problems = []
        p = self.params
        for s in range(1, self.n + 1):
            stream = []
            for k in range(1, p.records + 1):
                stream += L.log_record(k, p.payload, p.session, s)
            got = self.station(s)
            if got["committed"] != len(stream):
                problems.append(f"station {s}: the central holds {got['committed']} registers, "
                                f"the logger wrote {len(stream)}")
            elif got["sum"] != L.fletcher(stream):
                problems.append(f"station {s}: checksum {got['sum']}, want {L.fletcher(stream)}")
            if got["failed"]:
                problems.append(f"station {s}: {got['failed']} failed transfer(s)")
        return problems

    def radio_stats(self, stations=None):
        """Radio counters summed over `stations` (default all), and the kernel's."""
        return radio_stats(self.lib, self.sim, stations or range(1, self.n + 1))

