"""The interop matrix of issue 11: our blocks (plc/ programs in the soft-PLC) against the note-only
peer (peers/mippeer) over the emulated modems and radio.

Two ways to run a cell, one judge and one classification (cell.py: CellRun.run):
  kernel    (the default; kernel.py) our program as a soft-PLC of the co-simulation kernel
            (cosim/, mipcosim.sim.LoggerLink) and the peer as a participant of the same lockstep
            virtual time, its requests handed to the kernel's emulator core: deterministic by
            seed, every time (bound, caps, "error after t s") in virtual seconds;
  realtime  (--realtime; RealtimeRun) the soft-PLC executable and the `mip-peer` process over
            build/emulator/mip-emulator on 127.0.0.1, in real time.

Axes: ours {sender, receiver} x peer reading {strict, lenient} x fault {none, loss 30 %,
restart of our soft-PLC, restart of the peer} x layout {uni, bi} x MIP mode {dynamic, static}.

"ours = sender": our outstation (plc/outstation*.st, MIP_Sender / MIP_Link) against a note
central; "ours = receiver": our central (plc/central*.st, MIP_Receiver / MIP_Link) against a note
outstation. In the bidirectional layout both streams run and both are checked.

A cell's outcome:
  complete   every stream: the receiving side holds the sender's records exactly once, in
             order, register for register, and the sending side saw its last record
             acknowledged (our sender: "everything read out"; the peer: 0xFFFF came back);
  error      one of our blocks reported a failure (xError, its error id) within the bound
             (BOUND_FACTOR x tTimeout after the fault; after the start without a fault);
  FAIL       data lost or duplicated silently (a completed transfer that differs), an error
             later than the bound, or neither completion nor an error (a hang).
"""
from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path

from plcharness.procs import stop

# the matrix's names, defined in cell.py (shared with kernel.py) and used from here by
# __main__ and the tests
from .cell import (EMU, FAST_RADIO, FAULTS, LAYOUTS, MODES, OURS, READINGS, REALISTIC_RADIO,  # noqa: F401
                   PEER, Cell, CellRun, Config, L, MatrixError, PeerProc, Result, all_cells,
                   build_programs, demo, pipelined_applies, start_emulator)
from .kernel import KernelRun
from .kernel import build_programs as kernel_programs

class RealtimeRun(CellRun):
    """A cell in real time: mip-emulator, the soft-PLC executable and the mip-peer process on
    127.0.0.1 (`--realtime`)."""

    FAILURES = (demo.DemoError,)

    def __init__(self, cell: Cell, cfg: Config, progs, workdir: Path, seed: int):
        super().__init__(cell, cfg, progs, workdir, seed)
        self.procs = demo.Procs()
        self.slave = None
        self.lives = 0

    # -- processes
    def start(self):
        self.start_emulator()
        if self.cell.ours == "sender":      # the receiving side first, so the sender finds it
            self.start_peer()
            self.start_plc()
        else:
            self.start_plc()
            self.start_peer()

    def start_emulator(self):
        loss = self.cfg.loss if self.cell.fault == "loss30" else 0.0
        self.mdp, self.trm = start_emulator(
            self.procs, self.dir, self.seed, FAST_RADIO, loss,
            self.cfg.static_registers if self.static else 0)

    def start_plc(self):
        role = "outstation" if self.cell.ours == "sender" else "central"
        self.lives += 1
        name = f"{role}-{self.lives}"
        conf = self.dir / f"{name}.conf"
        conf.write_text(L.outstation_config(self.trm) if role == "outstation"
                        else L.central_config(self.mdp, 1))
        port = demo.free_port()
        exe = self.progs[role, self.bidi].executable
        self.procs.start(name, [str(exe), "-c", str(conf), "-s", f"127.0.0.1:{port}"],
                         self.dir / f"{name}.log")
        self.slave = demo.Slave(port)
        try:
            self.slave.connect(time.monotonic() + 10)
        except demo.DemoError as e:
            raise MatrixError(str(e)) from None
        self.plc_name = name
        self.slave.write(0, self.ours_params())

    def stop_plc(self):
        for i, (n, p, f, _) in enumerate(self.procs.procs):
            if n == self.plc_name:
                stop(p, timeout=10)
                f.close()
                del self.procs.procs[i]
                break
        self.slave.close()

    def start_peer(self):
        role = "central" if self.cell.ours == "sender" else "outstation"
        self.peer_life = getattr(self, "peer_life", 0) + 1
        self.peer_out = self.dir / f"peer-{self.peer_life}.json"
        args = [role, "--port", str(self.mdp if role == "central" else self.trm), "--unit", "1",
                "--layout", self.cell.layout, f"--{self.cell.reading}", "--drive", self.cfg.drive,
                "--period", str(self.cfg.peer_period_s),
                "--retransmit", str(self.cfg.peer_retransmit_s),
                "--request", str(self.cfg.peer_retransmit_s), "--timeout", "600",
                "--expect", "1000000", "--out", str(self.peer_out)]
        if role == "outstation" or self.bidi:
            args += ["--records", str(self.cfg.records), "--record-size", str(self.payload),
                     "--seed", str(self.peer_seed)]
        if self.static:
            args += ["--static-registers", str(self.cfg.static_registers)]
        self.peer = PeerProc(args, self.dir / f"peer-{self.peer_life}.log")

    def restart_ours(self):
        self.stop_plc()
        self.start_plc()

    def restart_peer(self):
        self.peer.stop()
        self.start_peer()

    def stop(self):
        if self.peer is not None:
            self.peer.stop()
        if self.slave is not None:
            self.slave.close()
        self.procs.stop()

    def check(self):
        self.procs.check_alive()
        self.peer.alive_or_raise()

    def clock(self):
        return time.monotonic()

    def pause(self):
        time.sleep(0.05)

    # -- observation
    def plc_words(self):
        b = L.peer_base(1)
        return self.slave.read(b, L.W_BASE + L.WINDOW)

    def peer_received(self):
        try:
            return json.loads(self.peer_out.read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            return {"transfers": [], "open": []}

    def peer_seen(self, kind, number):
        return self.peer.seen(kind, number)

    def peer_acknowledged(self):
        return [e[1] for e in self.peer.events if e[0] == "acknowledged"]

    def lost_blocks(self):
        trace = demo.TraceStats(self.dir / "trace.jsonl")
        trace.update()
        return trace.blocks_lost


def run_cell(cell: Cell, cfg: Config, progs, workdir: Path, seed: int = 1,
             realtime=False) -> Result:
    """One cell; progs: what programs(..., realtime) returned."""
    workdir.mkdir(parents=True, exist_ok=True)
    if realtime:
        if not EMU.is_file():
            raise MatrixError(f"{EMU} missing: run make")
        return RealtimeRun(cell, cfg, progs, workdir, seed).run()
    return KernelRun(cell, cfg, progs, workdir, seed).run()


def programs(outdir, realtime=False):
    """The example programs for run_cell: soft-PLC executables (realtime) or the kernel's
    builds (mipcosim.sim.build)."""
    if realtime:
        return build_programs(outdir)
    return kernel_programs(outdir)


def run_matrix(cells, cfg: Config, workdir: Path, progress=None, realtime=False):
    progs = programs(workdir / "build", realtime)
    results = []
    t = time.monotonic()
    for i, cell in enumerate(cells):
        r = run_cell(cell, cfg, progs, workdir / cell.key.replace("/", "-"), seed=1 + i,
                     realtime=realtime)
        results.append(r)
        if progress:
            progress(i + 1, len(cells), r)
    doc = {"config": asdict(cfg) | {"bound_s": cfg.bound_s},
           "clock": "real" if realtime else "virtual",
           "seconds": round(time.monotonic() - t, 1),
           "results": [asdict(r) for r in results]}
    if not realtime:
        doc["virtual_seconds"] = round(sum(r.virtual_s or 0 for r in results), 1)
    return doc
