"""Co-simulation driver: the example programs (plc/) as soft-PLCs and the emulator core, in one
process, in lockstep virtual time (cosim/README.md)."""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from plcharness import Plc, PlcError
from plcharness.build import build_program

from . import programs as L
from .kernel import (FATE_FN, LIBDIR, MS, SEC, SCAN_FN, TRACE_FN, CosimError, Kernel,  # noqa: F401
                     Radio, Stats, kernel_lib, radio_stats, read_taps)

REPO = L.REPO
_BUILDS = {}


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
    # station 1's ranges are the vendor stand-ins' request channel (mipcosim/vendor_glue.py): True for
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
    """What LoggerLink, Network and SoeChain share: their Kernel (self.kernel) and PLCs
    (self.plcs), virtual time, closing (the PLCs first, then the kernel)."""

    kernel: Kernel | None = None
    plcs: dict = {}

    def put_named(self, who, plc, snapshot=None):
        """Starts or restarts PLC `who` as `plc` (a warm restart: with its snapshot, loaded
        after config_init__, before the first scan); returns its id (self.ids). The PLC it
        replaces is closed and its snapshots counted (self.snapshots_before)."""
        if snapshot is not None:
            plc.retain_load(snapshot)
        old = self.plcs.get(who)
        self.plcs[who] = plc
        self.ids[who] = self.kernel.put_plc(self.ids.get(who), plc, self.tick_ns, name=who)
        if old is not None:
            self.snapshots_before += old.retain_saves
            old.close()
        return self.ids[who]

    @property
    def lib(self):
        return self.kernel.lib

    @property
    def sim(self):
        """The C kernel (mipcosim *), for the emulator core's own API."""
        return self.kernel.handle

    @property
    def now(self):
        """Virtual time in ns; after close() the time it was closed at."""
        return self.kernel.now

    def _check(self, rc):
        self.kernel.check(rc)

    def close(self):
        for plc in self.plcs.values():
            plc.close()
        self.plcs = {}
        if self.kernel is not None:
            self.kernel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class LoggerLink(_Kernel):
    """The logger link: outstation PLC(s), central PLC and the emulator network in one process
    (the SOE chain of issue 35 is mipcosim.chain.SoeChain)."""

    def __init__(self, setup: Setup, workdir: Path, trace=None):
        if not 1 <= setup.stations <= L.MAX_STATIONS:
            raise CosimError(f"stations {setup.stations}: the central program (plc/central.st) "
                             f"serves 1..{L.MAX_STATIONS}")
        if not 1 <= setup.tick_ms <= 1000:
            raise CosimError(f"tick_ms {setup.tick_ms}: use 1..1000")
        self.s = setup
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.kernel = Kernel(setup.stations, static=setup.static,
                             static_registers=setup.static_registers, loss_down=setup.loss,
                             loss_up=setup.loss, burst=setup.burst, seed=setup.seed,
                             radio=setup.radio, trace=trace)
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
        self.snapshots_before = 0   # snapshots of PLC instances that are gone
        for s in range(1, setup.stations + 1):
            self._start(("out", s))
        self._start(("cen", 0))

    # ------------------------------------------------------------------ wiring

    def session(self, who):
        return 1 + self.boots[who]

    def _start(self, who, start=None, snapshot=None, warm=False):
        role, s = who
        plc = Plc(self.out_build if role == "out" else self.cen_build, self.workdir,
                  config=self.out_conf if role == "out" else self.cen_conf)
        if plc.tick_ns != self.tick_ns:
            raise CosimError(f"{who}: the program scans every {plc.tick_ns} ns, the kernel every {self.tick_ns}")
        plc.retain_in_memory(self.s.retain_period_ms * MS)
        pid = self.put_named(who, plc, snapshot)     # snapshot: restart() checked it applies
        if role == "out":
            self.kernel.connect(pid, plc, "trm", s, self.s.transport)
        else:
            for st in range(1, self.s.stations + 1):
                self.kernel.connect(pid, plc, f"mdp{st}", 0, self.s.transport)
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
            self.kernel.tap(slot, pid, seq, hdr, nhdr, 2 if data else -1, data, 122)

        # the hand-written logic is the instance APP of the generated PROGRAM (plc/image/); a
        # station's blocks are in its STA<s> (PLC_RcvStation, PLC_LinkStation)
        if role == "out":
            b = L.peer_base(1)
            tap(20 + s, b + L.S_SEQ, 2, seq_src="APP.STA1.SRC" if bidi else "APP.SRC")
            if bidi:
                tap(30 + s, b + L.R_SEQ, 4, "OUTSTATIONBIDI.APP.STA1.LINK.ARECORD", "APP.STA1.STORE")
        else:
            for st in range(1, self.s.stations + 1):
                b = L.peer_base(st)
                fb = f"{prog}.APP.STA{st}.{'LINK' if bidi else 'RCV'}"
                tap(st, b + L.R_SEQ, 4, f"{fb}.ARECORD", f"APP.STA{st}.STORE")   # flags, number, len, error
                if bidi:
                    tap(10 + st, b + L.S_SEQ, 2, seq_src=f"APP.STA{st}.SRC")

    # ------------------------------------------------------------------ running

    def run_until(self, t_ns):
        try:
            self.kernel.run_until(t_ns)
        finally:
            self._drain()

    def run_for(self, ns):
        self.run_until(self.now + ns)

    def _drain(self):
        t = self.now
        for tap, plc, words in self.kernel.read_taps():
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
            self.kernel.replace(pid)
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
        self.kernel.replace(pid)
        self.restarts.append((self.now, who))
        self.events.append(Event(self.now, RESTART, pid, []))   # marker for the checker
        self.run_for(down_ns)
        self.boots[who] += 1
        self._start(who, start)

    def retain_stats(self):
        """{"snapshots": RETAIN snapshots taken by all PLCs (all their restarts included),
        "warm_restarts": warm restarts, "restored": those that restored a snapshot (the others
        were cold: no RETAIN variables, or no snapshot yet)}."""
        return {"snapshots": self.snapshots_before + sum(p.retain_saves for p in self.plcs.values()),
                "warm_restarts": self.warm_restarts, "restored": len(self.warm)}

    def sender_windows(self):
        """{1, 2}: the windows the senders of the running PLCs run (MIP_Sender's xPipe: uWindow
        2 applies only where P27 allows it, e.g. not in MIP_Link)."""
        out = set()
        for (role, _), plc in self.plcs.items():
            # the hand-written logic is the instance app of the generated PROGRAM (plc/image/)
            names = (["OUT0.APP.STA1.LINK.SND.XPIPE"] if self.s.bidi else ["OUT0.APP.SND.XPIPE"]) \
                if role == "out" else ([f"CEN0.APP.STA{st}.LINK.SND.XPIPE"
                                        for st in range(1, self.s.stations + 1)]
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
        return self.kernel.radio_stats()


class Network(_Kernel):
    """The largest MIP network: `stations` outstation soft-PLCs (plc/outstation.st, one per
    TRM-810) and ONE central program for all of them (plc/central_many.st, written by hand,
    with its image for n stations generated by mipprograms.image_many: n receivers behind one
    shared Modbus client) on one MDP-810, in lockstep virtual time.
    Stations per central and the scan tick are parameters. Delivery is checked per station
    from the central's record stores: registers committed and their Fletcher sums against
    what each logger wrote (check()); LoggerLink's per-event taps need a %MW block per station,
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
        self.kernel = Kernel(stations, loss_down=loss, loss_up=loss, seed=seed,
                             radio=radio or Radio.realistic())
        self.plcs = {}
        try:
            from mipprograms.image_many import generate
            src = self.workdir / f"src-many-{stations}" / "central_many_io.st"
            src.parent.mkdir(parents=True, exist_ok=True)
            text = generate(stations)
            if not src.is_file() or src.read_text() != text:
                src.write_text(text)
            lib_src = L.lib_sources() + [str(L.PLC_DIR / "PLC_Logger.st"),
                                         str(L.PLC_DIR / "central_many.st")]
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
        pid = self.kernel.add_plc(plc, self.tick_ns, name=who)
        for dev, ep in wires:
            self.kernel.connect(pid, plc, dev, ep)
        for i, w in enumerate(params.words()):
            plc[f"%MW{i}"] = w

    def run_for(self, ns):
        self.kernel.run_for(ns)

    def central(self, addr):
        """%MW addr of the central (layout M_*: its shared client's statistics)."""
        return self.plcs[("cen", 0)][f"%MW{addr}"]

    def station(self, s):
        """What the central holds of station s: {"committed", "sum", "transfers", "failed",
        "records"} from its PLC_RecordStore; and whether the outstation read out all."""
        cen = self.plcs[("cen", 0)]
        p = f"CEN0.STA{s}.STORE."
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
        return self.kernel.radio_stats(stations)

