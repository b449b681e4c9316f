"""The whole chain of issue 35 in the co-simulation, one virtual time, deterministic:

    relay (C core, mipcosim_relay_add) -> outstation soft-PLC (plc/outstation_soe.st:
    MIP_SoeReader -> PLC_SoeLog -> MIP_Sender) -> radio (emulator core) -> central soft-PLC
    (plc/central_soe.st: MIP_Receiver, xAckByCaller -> PLC_SoeHandOver -> MIP_SoeServer) ->
    the SCADA master stand-in (mippeer.scada.SoeMaster, the pull way)

The SCADA is a participant of the kernel's lockstep loop (a scan function of its own,
mipcosim_plc_add, as interop/ adds the note peer): every `scada_period_ms` of virtual time it
polls the central's Modbus slave once. Its Modbus TCP frames go through a socketpair whose
other end the central's slave serves (plcrt_slave_add_client); the request is served at once
(plcrt_slave_poll), so a request takes no virtual time and the program sees a write in its
next scan, as with a slave that answers between two scans.

    ch = SoeChain(workdir, events=script, loss=0.3, retain=True)
    ch.run_to_end(limit_ns)             # every event at the SCADA, or the limit
    ch.restart("out", warm=True)        # ("out" | "cen"), warm / graceful as mipcosim.sim
    problems = check_chain(ch)          # [] when every event arrived once, in order, unchanged
"""
from __future__ import annotations

import ctypes
import socket
from dataclasses import dataclass, field
from pathlib import Path

from plcharness import Plc

from . import programs as L
from .relay import Relay
from .kernel import MS, SEC, SCAN_FN, CosimError, Kernel, Radio
from .sim import _Kernel, build
from .chainprograms import (  # noqa: F401 (the chain's API, one import for its users)
    ORIGIN_MS, SOE_BASE, PROGRAMS, PUSH_PROGRAM, UNICOS_MARKER, UNICOS_IMAGE,
    HELPERS, OUT_STORED, OUT_SENT, OUT_LEVEL, OUT_DONE, OUT_FAILED,
    OUT_ERROR, OUT_FLAGS, OUT_RETRANS, CEN_RECORDS, CEN_PUT, CEN_ACKED,
    CEN_BAD_ACKS, CEN_BAD_RECORDS, CEN_DUP, CEN_FAILED, CEN_FLAGS, CEN_QUEUED,
    PUSH_RECORDS, PUSH_EVENTS, PUSH_FRAMES, PUSH_RETRIES, PUSH_PASSIVE, PUSH_DUP,
    PUSH_FAILED, PUSH_FLAGS, program_sources, relay_sections, slave_section, unicos_sections,
    central_push_config, outstation_soe_config, central_soe_config, SoeParams, script, expected)
from .chaincheck import ChainReport, check_chain  # noqa: F401


class _ScadaClient:
    """mippeer.scada.Client's transport, in process: a socketpair to the central's slave, the
    request served in the same virtual instant. Made anew when the central restarted."""

    def __init__(self, chain):
        self.chain = chain

    def bind(self, client):
        ch = self.chain

        def connect():
            if client.sock is None:
                plc = ch.plcs.get("cen")
                if plc is None or not ch.up["cen"]:
                    from mippeer.scada import ScadaError
                    raise ScadaError("central: not running")
                a, b = socket.socketpair()
                if plc.library.plcrt_slave_add_client(plc.handle, b.detach()) != 0:
                    a.close()
                    raise CosimError("central: no Modbus slave ([slave] section)")
                a.settimeout(1.0)
                client.sock = a
                client.plc = plc

        def after_send():
            plc = getattr(client, "plc", None)
            if plc is not None and ch.plcs.get("cen") is plc and ch.up["cen"]:
                plc.library.plcrt_slave_poll(plc.handle, 0)

        client._connect = connect
        client.after_send = after_send


@dataclass
class ChainSetup:
    events: list = field(default_factory=lambda: script(60))
    loss: float = 0.0
    seed: int = 1
    radio: Radio = field(default_factory=Radio)
    params: SoeParams = field(default_factory=SoeParams)
    handover: str = "pull"         # "pull": MIP_SoeServer + the SCADA; "push": MIP_UnicosEvents + WinCC OA
    scada_period_ms: int = 50
    scada_reack_s: float = 1.0
    relay_capacity: int = 1000
    tick_ms: int = 10
    retain_period_ms: int = 1000
    compiler: str = "stc"


class SoeChain(_Kernel):
    """relay -> outstation PLC -> radio -> central PLC -> SCADA, in one process."""

    def __init__(self, setup: ChainSetup, workdir: Path, trace=None):
        from mippeer.scada import Client, SoeMaster
        self.s = setup
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.plcs = {}
        self.kernel = Kernel(1, loss_down=setup.loss, loss_up=setup.loss, seed=setup.seed,
                             radio=setup.radio, trace=trace)
        try:
            self.tick_ns = setup.tick_ms * MS
            if setup.handover not in ("pull", "push"):
                raise CosimError(f"handover {setup.handover!r}: pull or push")
            self.push = setup.handover == "push"
            self.builds = {role: build(f"{role}_{setup.handover if role == 'cen' else 'soe'}", False,
                                       self.workdir, setup.compiler, setup.tick_ms,
                                       program_sources(role, setup.handover)) for role in PROGRAMS}
            ret = lambda who: L.retain_section(self.workdir / f"{who}.retain", setup.retain_period_ms)
            self.confs = {"out": self.workdir / "outstation_soe.conf",
                          "cen": self.workdir / "central_soe.conf"}
            self.confs["out"].write_text(outstation_soe_config(retain=ret("out")))
            self.confs["cen"].write_text(central_push_config(retain=ret("cen")) if self.push
                                         else central_soe_config(retain=ret("cen")))
            # push: WinCC OA's redundant pair of UNICOS drivers, devices of the central PLC
            self.drivers, self.driver_up, self.pydevs = {}, {"a": True, "b": True}, []
            self.active = "b" if setup.params.active_b else "a"
            self.failovers = 0
            if self.push:
                from mippeer.unicos import UnicosConfig, UnicosDriver
                self.drivers = {d: UnicosDriver(d.upper(), UnicosConfig(marker=UNICOS_MARKER))
                                for d in "ab"}
            self.exp_keys = [(e[3], e[4] // 10 * 10 if self.push else e[4])
                             for e in expected(setup.events)]
            self.relay = Relay(setup.events, kernel=self.kernel, capacity=setup.relay_capacity,
                               origin_ms=ORIGIN_MS)
            self.old_relays = []        # the relay's counters before each restart_relay()
            self.at_risk = set()        # events a relay restart took before the outstation had them
            self.ids = {}
            self.up = {"out": False, "cen": False, "scada": True}
            self.restarts = []          # (t_ns, who, kind): kind cold | warm | graceful
            self.last_snapshot = {}
            self.snapshots_before = 0
            self.rows = []              # what the SCADA took (mippeer.scada.entry dicts)
            self.taken_at = []          # the virtual time (ns) each row was taken
            self.distinct = set()       # (value, time stamp) of the entries taken
            self.scada_failures = 0
            self.scada_outages = 0
            for who in ("out", "cen"):
                self._start(who)
            self.client = Client("central", 0, timeout=1.0)
            _ScadaClient(self).bind(self.client)
            self.scada = SoeMaster(self.client, SOE_BASE, self._sink, setup.scada_reack_s)
            self._scada_error = None
            if not self.push:           # the pull way's SCADA polls; the push way's drivers wait
                self.scada_id = self.kernel.add_scan(SCAN_FN(self._scada_round),
                                                     setup.scada_period_ms * MS)
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ wiring

    def _start(self, who, snapshot=None):
        plc = Plc(self.builds[who], self.workdir, config=self.confs[who])
        if plc.tick_ns != self.tick_ns:
            raise CosimError(f"{who}: the program scans every {plc.tick_ns} ns, the kernel every {self.tick_ns}")
        lib = plc.library
        lib.plcrt_slave_add_client.argtypes = [ctypes.c_void_p, ctypes.c_int]
        lib.plcrt_slave_poll.argtypes = [ctypes.c_void_p, ctypes.c_int]
        plc.retain_in_memory(self.s.retain_period_ms * MS)
        if who == "cen" and self.push:      # before its first scan (pydevice.py)
            from .pydevice import PyDevice
            self.pydevs = [PyDevice(plc, f"unicos_{d}", self._driver(d)) for d in "ab"]
        self.put_named(who, plc, snapshot)
        if who == "out":
            self.kernel.connect(self.ids[who], plc, "trm", 1)
            self.relay.connect(self.ids[who], plc, "relay")
        else:
            self.kernel.connect(self.ids[who], plc, "mdp1", 0)
        for i, w in enumerate(self.s.params.words()):
            plc[f"%MW{i}"] = w
        self.up[who] = True

    def _driver(self, d):
        """Driver d's Modbus handler as a device of the central: its new events are the
        control system's (rows, with the driver's name)."""
        def handle(adu):
            if not self.driver_up[d]:
                return None                       # the driver is down: no answer
            drv = self.drivers[d]
            n0 = len(drv.events)
            rsp = drv.handle(adu)
            for ev in drv.events[n0:]:
                self.rows.append({"driver": d, "type_bit": ev["value"] >> 16, "address": ev["offset"],
                                  "cause_type": None, "value": ev["value"] & 0xFFFF,
                                  "ts_ms": ev["ts_10ms"] * 10})
                self.taken_at.append(self.now)
                self.distinct.add((ev["value"] & 0xFFFF, ev["ts_10ms"] * 10))
            return rsp
        return handle

    def relay_stats(self):
        """The relay's counters over its restarts; entries: in the relay running now."""
        st = dict(self.relay.stats())
        for old in self.old_relays:
            for k in ("generated", "dropped", "acknowledged", "bad_acks", "reset_cleared"):
                st[k] += old[k]
        return st

    def restart_relay(self):
        """The relay restarts (mipcosim_relay_restart): its recorder empty, its sequence number 0
        (MIP_SoeReader: a relay that started), the events still to come scripted anew. The
        entries it held, not acknowledged, are gone with it: the relay's loss, which the check
        counts apart (lost_at_relay); those the logger already stored must still arrive."""
        st = self.relay.stats()
        acked = st["acknowledged"] + sum(o["acknowledged"] for o in self.old_relays)
        generated = st["generated"] + sum(o["generated"] for o in self.old_relays)
        self.at_risk.update(range(acked, generated))    # events come in order, go oldest first
        self.old_relays.append(dict(st))
        rest = self.s.events[generated:]
        if rest and int(round(rest[0][0] * 1e9)) <= self.now:
            raise CosimError(f"restart_relay: event {generated + 1} is due but not recorded")
        self.relay.restart(rest)
        self.restarts.append((self.now, "relay", "power"))

    def failover(self):
        """Push: the other driver of the pair becomes the active one (the program reads flags
        bit 3 every scan)."""
        self.active = "b" if self.active == "a" else "a"
        self.s.params.active_b = self.active == "b"
        self.failovers += 1
        if self.up["cen"]:
            self.plcs["cen"]["%MW3"] = self.s.params.words()[3]

    def driver_outage(self, down_ns, which=None):
        """Push: a driver (the active one by default) answers nothing for down_ns."""
        d = which or self.active
        self.driver_up[d] = False
        self.scada_outages += 1
        self.run_for(down_ns)
        self.driver_up[d] = True

    def _sink(self, entries):
        """The SCADA's store: the entries of one offer, before it acknowledges them."""
        self.rows.extend(entries)
        self.taken_at.extend([self.now] * len(entries))
        self.distinct.update((e["value"], e["ts_ms"]) for e in entries)

    def latencies_ns(self):
        """Per event taken (first time): virtual time from the relay event to the SCADA."""
        first = {}
        for r, t in zip(self.rows, self.taken_at):
            first.setdefault((r["value"], r["ts_ms"]), t)
        out = []
        for (t_s, w), e in zip(self.s.events, expected(self.s.events)):
            t = first.get((e[3], e[4]))
            if t is not None:
                out.append(t - int(round(t_s * 1e9)))
        return out

    def _scada_round(self, _rt, _n):
        """The SCADA's "scan": one poll of the central, at its due virtual time."""
        from mippeer.scada import ScadaError
        if not self.up["scada"]:
            return 0
        try:
            self.scada.poll(self.now / SEC)
        except ScadaError:
            self.scada_failures += 1
        except BaseException as e:      # noqa: BLE001 (handed back through the C loop)
            self._scada_error = e
            return -1
        return 0

    # ------------------------------------------------------------------ running

    def run_until(self, t_ns):
        try:
            self.kernel.run_until(t_ns)
        except CosimError:
            e, self._scada_error = self._scada_error, None
            if e is not None:
                raise CosimError(f"the SCADA failed: {type(e).__name__}: {e}") from e
            raise

    def run_for(self, ns):
        self.run_until(self.now + ns)

    def mw(self, who, addr):
        return self.plcs[who][f"%MW{addr}"]

    def mw32(self, who, addr):
        return self.mw(who, addr) | self.mw(who, addr + 1) << 16

    def finished(self):
        """Every relay event happened, the SCADA took as many distinct entries as there are
        events (a duplicate does not count), the relay's recorder is empty."""
        st = self.relay_stats()
        return (st["generated"] >= len(self.s.events) and st["entries"] == 0
                and all(k in self.distinct or i in self.at_risk
                        for i, k in enumerate(self.exp_keys)))

    def settled(self):
        """Nothing is left anywhere on the way: every relay event happened, the relay, the
        outstation's logger and the central's server hold none (what the SCADA lacks now will
        never come: lost)."""
        st = self.relay_stats()
        return (st["generated"] >= len(self.s.events) and st["entries"] == 0
                and self.up["out"] and self.up["cen"]
                and self.mw("out", OUT_LEVEL) == 0
                and (self.push or self.mw("cen", CEN_QUEUED) == 0))

    def run_to_end(self, limit_ns, step_ns=SEC, settle_ns=2 * SEC):
        """Run until finished() (then settle_ns more, so late duplicates show), until nothing is
        left on the way for 5 s (settled(): the rest is lost), or until limit_ns."""
        quiet = 0
        while self.now < limit_ns:
            self.run_for(step_ns)
            quiet = quiet + step_ns if self.settled() else 0
            if quiet >= 5 * SEC and not self.finished():
                return False
            if self.finished():
                self.run_for(settle_ns)
                return True
        return False

    def restart(self, who, kind="warm", down_ns=500 * MS):
        """A PLC restart ("out" | "cen"): off for down_ns (its modem, the relay and the SCADA go
        on), then a fresh instance. kind "warm": it gets the RETAIN variables of its last complete
        snapshot (plcrt's kill -9); "graceful": a snapshot taken at the stop (SIGTERM); "cold":
        nothing retained (the outstation's logger with it: its stored entries are gone)."""
        if kind not in ("warm", "graceful", "cold"):
            raise CosimError(f"restart kind {kind!r}: warm, graceful or cold")
        old = self.plcs[who]
        snapshot = None
        if kind == "graceful":
            snapshot = old.retain_save()
        elif kind == "warm":
            snapshot = old.retain_last() or self.last_snapshot.get(who)
        if snapshot is not None:
            self.last_snapshot[who] = snapshot
        self.kernel.replace(self.ids[who])
        self.up[who] = False
        if who == "cen":
            self.client.close()
        self.restarts.append((self.now, who, kind if snapshot is not None or kind == "cold" else "cold"))
        self.run_for(down_ns)
        self._start(who, snapshot)

    def scada_outage(self, down_ns):
        """The control system away for down_ns (it polls nothing), then back: a restarted
        master that knows the offer it took last (mippeer.scada.resume: from its own file)."""
        from mippeer.scada import SoeMaster
        self.up["scada"] = False
        self.scada_outages += 1
        self.client.close()
        self.run_for(down_ns)
        last, offers = self.scada.last, self.scada.offers
        self.scada = SoeMaster(self.client, SOE_BASE, self._sink, self.s.scada_reack_s,
                               last=last, offers=offers)
        self.up["scada"] = True

    def radio_stats(self):
        return self.kernel.radio_stats([1])

    def snapshots(self):
        return self.snapshots_before + sum(p.retain_saves for p in self.plcs.values())

    def close(self):
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
        super().close()
