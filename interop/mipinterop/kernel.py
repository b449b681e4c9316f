"""The interop matrix in the co-simulation kernel (the default; cell.py has the cells, the judge
and the classification, the same for both ways of running a cell).

Our side is the example program (plc/outstation*.st or plc/central*.st) as a soft-PLC of
mipcosim.sim.LoggerLink: the kernel's builds, runtime configs, in-process transport and restart. The
chain's other PLC is switched off before it ever scans; the note-only peer takes its place as a
participant of the same lockstep loop (a scan function of its own, mipcosim_plc_add): every
peer_period_s of virtual time it runs one round of mippeer.cli.Loop (read its modem,
Peer.step, write), its Modbus requests built by pymodbus as over TCP (Modem.in_process) and
handed to the emulator core at that virtual time (mipcosim_request). One clock for everything:
a cell is a function of its configuration and its seed, and nothing waits for real time.

Timing compared with the real-time run (matrix.RealtimeRun): the peer reads every 20 ms exactly
(in real time 20 ms plus its Modbus round trips), requests take no time, the receiving side
starts one scan tick (10 ms) before the sender, the matrix looks after every scan tick (real
time: every 50 ms), and a restarted side is off for Config.down_s (0.5 s; real time: as long as
stopping and starting the process took). "After the fault" counts from when the restarted side
runs again, as in real time.
"""
from __future__ import annotations

import contextlib
import ctypes
from pathlib import Path

from mipcosim import programs as L
from mipcosim import sim as S
from mippeer.cli import Loop, received
from mippeer.modem import Modem
from mippeer.peer import Peer

from .cell import CellRun, MatrixError, demo

RESPONSE_MAX = 300               # MIPEMU_RESPONSE_MAX: room for any response ADU


def build_programs(outdir):
    """The four example programs, built once per process by the kernel's build (cached by
    mipcosim.sim.build; every LoggerLink after this takes them from there)."""
    from plcharness.build import BuildError
    for role in ("outstation", "central"):
        for bidi in (False, True):
            try:
                S.build(role, bidi, Path(outdir))
            except BuildError as e:
                raise MatrixError(f"building plc/{role}{'_bidi' if bidi else ''}.st: {e}") from None
    return {}


class KernelRun(CellRun):
    """A cell in the co-simulation kernel, in virtual time (clock(): virtual seconds)."""

    FAILURES = (S.CosimError,)

    def __init__(self, cell, cfg, progs, workdir: Path, seed: int):
        super().__init__(cell, cfg, progs, workdir, seed)
        self.chain = None
        self.peer_id = None
        self.peer_life = 0
        self.faults = []             # (switched off at ns, running again at ns, "ours" | "peer")
        self._peer_error = None
        self._scan = S.SCAN_FN(self._peer_round)     # referenced for as long as the kernel may call it
        self._words = None

    # -- setting up
    def start(self):
        cfg, cell = self.cfg, self.cell
        setup = S.Setup(stations=1, static=self.static, static_registers=cfg.static_registers,
                        polled=cfg.drive == "polled", bidi=self.bidi,
                        loss=cfg.loss if cell.fault == "loss30" else 0.0, seed=self.seed,
                        records=cfg.records, payload=self.payload, timeout_ms=cfg.timeout_ms,
                        radio=S.Radio())          # the fast radio (matrix.FAST_RADIO)
        self.trace = self.dir / "trace.jsonl"
        self.chain = c = S.LoggerLink(setup, self.dir, trace=self.trace)
        self.tick = c.tick_ns
        self._rsp = ctypes.create_string_buffer(RESPONSE_MAX)
        self.ours = ("out", 1) if cell.ours == "sender" else ("cen", 0)
        other = ("cen", 0) if cell.ours == "sender" else ("out", 1)
        c.kernel.replace(c.ids[other])
        # our program idles one scan (%MW0 = 0) before its parameters say start, as the
        # process does before the real-time run writes them (started with them in its first
        # scan, the bidirectional static programs raise a write of length 0 once); the
        # receiving side starts one scan tick before the sender
        self._set_params(False)
        if cell.ours == "receiver":
            self._run_to(c.now + self.tick)
            self._set_params(True)
            self._run_to(c.now + self.tick)
            self._peer_start()
        else:
            self._peer_start()
            self._run_to(c.now + self.tick)
            self._set_params(True)

    def _set_params(self, start):
        """Our program's parameters, written before its next scan (the real-time run writes the
        same words over Modbus after each start), and a view of its peer block."""
        plc = self.chain.plcs[self.ours]
        for i, w in enumerate(self.ours_params(start)):
            plc[f"%MW{i}"] = w
        base, n = L.peer_base(1), L.W_BASE + L.WINDOW
        addr = plc.address(f"%MW{base}")
        if plc.address(f"%MW{base + n - 1}") != addr + 2 * (n - 1):
            raise MatrixError(f"%MW{base}..{base + n - 1} are not contiguous in the image")
        self._words = (ctypes.c_uint16 * n).from_address(addr)

    def _peer_start(self):
        """A fresh peer (all state lost), scanned from now on every peer_period_s."""
        role, records, kw = self.peer_args()
        ep = 0 if role == "central" else 1
        kernel, rsp = self.chain.kernel, self._rsp

        def transact(adu):
            n = kernel.request(ep, adu, rsp)
            if n < 0:
                raise S.CosimError(kernel.errmsg())
            return rsp.raw[:n]

        modem = Modem.in_process(transact, "mdp" if role == "central" else "trm", unit=1)
        modem.connect()
        self.peer = Loop(Peer(role, records, **kw), modem)
        self.peer_life += 1
        self._peer_t0 = self.chain.now
        period = round(self.cfg.peer_period_s * S.SEC)
        if self.peer_id is None:
            self.peer_id = kernel.add_scan(self._scan, period)
        else:
            kernel.replace_scan(self.peer_id, self._scan, period)

    def _peer_round(self, _rt, _n):
        """The peer's "scan", called by mipcosim_run at its due virtual time."""
        try:
            self.peer.round((self.chain.now - self._peer_t0) / S.SEC)
            return 0
        except BaseException as e:        # noqa: BLE001  (handed back through the C loop)
            self._peer_error = e
            return -1

    @contextlib.contextmanager
    def _peer_errors(self):
        """A failed run whose cause is the peer's round: say what failed in the peer."""
        try:
            yield
        except S.CosimError:
            e, self._peer_error = self._peer_error, None
            if isinstance(e, (KeyboardInterrupt, SystemExit)):
                raise e from None
            if e is not None:
                raise S.CosimError(f"the peer failed: {type(e).__name__}: {e}") from None
            raise

    def _run_to(self, t_ns):
        with self._peer_errors():
            self.chain.run_until(t_ns)

    # -- the cell's hooks
    def stop(self):
        if self.chain is not None:
            self.chain.close()

    def clock(self):
        return self.chain.now / S.SEC

    def pause(self):
        self._run_to(self.chain.now + self.tick)

    def restart_ours(self):
        """LoggerLink's cold restart (off for down_s while the peer goes on, then a fresh instance of
        the program), with the interop's parameters: all state is lost, the logger's read-out
        pointer too (LoggerLink's own restart resumes there in a new session), as when the real-time
        run starts the process again."""
        t_off = self.chain.now
        with self._peer_errors():
            self.chain.restart(self.ours, down_ns=round(self.cfg.down_s * S.SEC))
        self._set_params(False)              # one idle scan, as at the first start
        self._run_to(self.chain.now + self.tick)
        self._set_params(True)
        self.faults.append((t_off, self.chain.now, "ours"))

    def restart_peer(self):
        """The peer stopped (not scanned, its modem keeps running) for down_s, then a new one."""
        t_off = self.chain.now
        self.chain.kernel.replace(self.peer_id)
        self._run_to(t_off + round(self.cfg.down_s * S.SEC))
        self._peer_start()
        self.faults.append((t_off, self.chain.now, "peer"))

    def plc_words(self):
        return list(self._words)

    def peer_received(self):
        if self.peer.peer.receiver is None:        # a sending peer of the uni layout
            return {"transfers": [], "open": []}
        return received(self.peer.peer)

    def peer_seen(self, kind, number):
        return self.peer.seen(kind, number)

    def peer_acknowledged(self):
        return [n for kind, n in self.peer.events if kind == "acknowledged"]

    def lost_blocks(self):
        if self.chain is not None and self.chain.sim:
            self.chain.lib.mipcosim_trace_file(self.chain.sim, None)    # flushed and closed
        stats = demo.TraceStats(self.trace)
        stats.update()
        return stats.blocks_lost

    def virtual_s(self):
        return None if self.chain is None or not self.chain.sim else self.chain.now / S.SEC
