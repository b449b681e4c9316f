"""A cell of the interop matrix and what every way of running it shares: the axes, the
configuration, the result, the note peer's process, the example programs' real-time builds, and
CellRun (the judge and the classification). matrix.py runs cells (RealtimeRun, run_matrix);
kernel.py runs them in the co-simulation kernel (KernelRun). Both import this module; it imports
neither (issue 45: the kernel.py <-> matrix.py cycle)."""
from __future__ import annotations

import itertools
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from mipcosim import programs as L
from mipdemo import common as demo            # noqa: F401  (Procs, Slave, free_port, TraceStats: for matrix, kernel, timing)
from mippeer.cli import logger_records
from plcharness.procs import stop

REPO = Path(__file__).resolve().parents[2]

EMU = REPO / "build" / "emulator" / "mip-emulator"
PEER = [sys.executable, "-m", "mippeer.cli"]

OURS = ("sender", "receiver")
READINGS = ("strict", "lenient")
FAULTS = ("none", "loss30", "restart-ours", "restart-peer")
LAYOUTS = ("uni", "bi")
MODES = ("dynamic", "static", "pipelined")
# "pipelined": dynamic mode with uWindow 2 of MIP_Sender / MIP_Link (st_lib/PROTOCOL.md P27):
# our sender's in the unidirectional layout, and both sides of ours in the bidirectional one
# (our outstation's or our central's MIP_Link sends too)


def pipelined_applies(ours, layout):
    """Whether a "pipelined" cell exists: our program sends a stream of its own."""
    return layout == "bi" or ours == "sender"
FAULT_TEXT = {"none": "no fault", "loss30": "30 % loss", "restart-ours": "restart ours",
              "restart-peer": "restart peer"}


class MatrixError(Exception):
    """The matrix could not run (build missing, a process would not start): not a cell result."""


# mip-emulator radio timing: the matrix runs on the fast radio; timing.py also on the realistic
# one (the co-simulation's Radio.realistic(): 9600 bit/s, 20 ms slot gap, 12 bytes overhead)
FAST_RADIO = ("--bitrate", "1000000", "--slot-gap-ms", "1")
REALISTIC_RADIO = ("--bitrate", "9600", "--slot-gap-ms", "20", "--overhead-bytes", "12")


def start_emulator(procs, workdir: Path, seed: int, radio=FAST_RADIO, loss=0.0,
                   static_registers=0):
    """Starts mip-emulator (1 station, free ports, trace in workdir/trace.jsonl) under `procs`;
    returns (mdp port, trm port)."""
    args = [str(EMU), "--mdp-port", "0", "--trm-base-port", "0", "--stations", "1",
            "--seed", str(seed), *radio, "--trace", str(workdir / "trace.jsonl"),
            "--loss-up", str(loss), "--loss-down", str(loss)]
    if static_registers:
        args += ["--mode", "static", "--static-registers", str(static_registers)]
    p = procs.start("mip-emulator", args, workdir / "emulator.log",
                    stdout=subprocess.PIPE, text=True)
    line = p.stdout.readline().strip()
    if not line.startswith("mip-emulator: listening"):
        raise MatrixError(f"mip-emulator did not start: {line!r}")
    fields = dict(kv.split("=", 1) for kv in line.split()[2:])
    return int(fields["mdp"].rsplit(":", 1)[1]), int(fields["trm"].split(",")[0])


@dataclass(frozen=True)
class Cell:
    ours: str
    reading: str
    fault: str
    layout: str
    mode: str

    @property
    def key(self):
        return "/".join((self.ours, self.reading, self.fault, self.layout, self.mode))

    @classmethod
    def parse(cls, key):
        parts = key.split("/")
        if len(parts) != 5:
            raise ValueError(f"cell {key!r}: want ours/reading/fault/layout/mode")
        c = cls(*parts)
        for v, axis in zip(parts, (OURS, READINGS, FAULTS, LAYOUTS, MODES)):
            if v not in axis:
                raise ValueError(f"cell {key!r}: {v!r} is not one of {', '.join(axis)}")
        if c.mode == "pipelined" and not pipelined_applies(c.ours, c.layout):
            raise ValueError(f"cell {key!r}: pipelined is window 2 of our sending side: our "
                             f"sender, or either side in the bi layout")
        return c


def all_cells():
    return [Cell(*v) for v in itertools.product(OURS, READINGS, FAULTS, LAYOUTS, MODES)
            if v[4] != "pipelined" or pipelined_applies(v[0], v[3])]


@dataclass
class Config:
    records: int = 6               # records per transfer
    payload: int = 20              # payload registers per record, dynamic mode
    static_registers: int = 24     # static mode: registers mirrored; payload = this - header
    timeout_ms: int = 500          # the blocks' tTimeout
    # the senders' uMaxRetries: unlimited (the demo's setting, and the hard case: a stuck
    # sender must not be rescued by giving up, it must say that the peer is out of step)
    max_retries: int = 0
    # the bound: this many tTimeout after the fault. st_lib/PROTOCOL.md (P11, P21): an error
    # after 3 tTimeout of out-of-step telegrams and the next telegram after that (at most one
    # more tTimeout), plus one tTimeout for the restarted side to open its session.
    bound_factor: float = 5.0
    restart_after: int = 3         # restart once this record was acknowledged
    loss: float = 0.3
    peer_retransmit_s: float = 0.5
    cap_s: float = 12.0            # give up on a cell this long after its start / its fault
    cap_loss_s: float = 25.0
    drive: str = "spontaneous"
    peer_period_s: float = 0.02    # the peer reads its modem (and may write) this often
    # kernel: a restarted side is off this long (the soft-PLC: LoggerLink.restart's down time; the
    # peer: its process start); "after the fault" counts from when it runs again
    down_s: float = 0.5

    @property
    def bound_s(self):
        return self.bound_factor * self.timeout_ms / 1000.0


@dataclass
class Result:
    cell: str
    outcome: str                   # complete | error | FAIL
    passed: bool
    text: str                      # the table's words: "complete", "error PEER_RESET after 1.2 s", ...
    error: str = ""
    error_after_s: float | None = None
    errors: list = field(default_factory=list)
    streams: dict = field(default_factory=dict)
    seconds: float = 0.0           # wall time of the cell
    lost_telegrams: int = 0        # of them carrying a block (record or acknowledgement)
    detail: str = ""               # counters at the end, to see where a cell got stuck
    virtual_s: float | None = None  # kernel: the cell's virtual time (start to verdict)


# ----------------------------------------------------------------------------- processes

class PeerProc:
    """One life of mip-peer; its event lines are collected by a thread."""

    def __init__(self, args, log):
        self.events = []
        self.log = log
        self.p = subprocess.Popen(PEER + args + ["--events"], stdout=subprocess.PIPE,
                                  stderr=open(log, "w"), stdin=subprocess.DEVNULL, text=True,
                                  start_new_session=True)
        self.t = threading.Thread(target=self._read, daemon=True)
        self.t.start()

    def _read(self):
        for line in self.p.stdout:
            self.events.append(line.split())

    def seen(self, kind, number):
        return any(e[:2] == [kind, str(number)] for e in list(self.events))

    def alive_or_raise(self):
        if self.p.poll() is not None and self.p.returncode != 0:
            tail = Path(self.log).read_text().strip().splitlines()[-1:]
            raise MatrixError(f"mip-peer exited with {self.p.returncode}: {' '.join(tail)}")

    def stop(self):
        stop(self.p, timeout=5)
        self.t.join(timeout=2)


def build_programs(outdir):
    from plcharness.build import BuildError, build_program
    progs = {}
    for role in ("outstation", "central"):
        for bidi in (False, True):
            try:
                progs[role, bidi] = build_program(L.program_sources(role, bidi),
                                                  Path(outdir) / f"{role}{'_bidi' if bidi else ''}")
            except BuildError as e:
                raise MatrixError(f"building plc/{role}{'_bidi' if bidi else ''}.st: {e}") from None
    return progs


class CellRun:
    """One cell: what each stream should carry, the judge, and the run loop that classifies the
    outcome. Subclasses bring the participants and the clock: RealtimeRun (processes, real
    time) and kernel.KernelRun (the co-simulation kernel, virtual time)."""

    FAILURES = ()                  # exceptions of the subclass's machinery: MatrixError

    def __init__(self, cell: Cell, cfg: Config, progs, workdir: Path, seed: int):
        self.cell, self.cfg, self.progs, self.dir = cell, cfg, progs, workdir
        self.seed = seed
        self.bidi = cell.layout == "bi"
        self.static = cell.mode == "static"
        header = 2 if self.bidi else 1
        self.payload = cfg.static_registers - header if self.static else cfg.payload
        self.session = 7
        self.peer_seed = 11
        self.peer = None
        self.ours_restarted = self.peer_restarted = False

    # -- what each stream should carry
    def up_want(self):
        if self.cell.ours == "sender":
            return [L.log_record(n, self.payload, self.session, 1)
                    for n in range(1, self.cfg.records + 1)]
        return logger_records(self.cfg.records, self.payload, self.peer_seed)

    def down_want(self):
        if self.cell.ours == "receiver":
            return [L.log_record(n, self.payload, self.session ^ 0x8000, 1)
                    for n in range(1, self.cfg.records + 1)]
        return logger_records(self.cfg.records, self.payload, self.peer_seed)

    def ours_params(self, start=True):
        """Our program's parameters (%MW0..), the same at every start: a restart loses all."""
        return L.Params(records=self.cfg.records, payload=self.payload, session=self.session,
                        station=1, polled=self.cfg.drive == "polled", static=self.static,
                        timeout_ms=self.cfg.timeout_ms,
                        chunk=self.cfg.static_registers if self.static else 123,
                        max_retries=self.cfg.max_retries,
                        window=2 if self.cell.mode == "pipelined" else 1).words(start)

    def peer_args(self):
        """(role, records or None, Peer keyword arguments) of the note peer of this cell."""
        role = "central" if self.cell.ours == "sender" else "outstation"
        records = (logger_records(self.cfg.records, self.payload, self.peer_seed)
                   if role == "outstation" or self.bidi else None)
        kw = dict(layout=self.cell.layout, drive=self.cfg.drive,
                  lenient=self.cell.reading == "lenient",
                  retransmit_s=self.cfg.peer_retransmit_s, request_s=self.cfg.peer_retransmit_s,
                  static_registers=self.cfg.static_registers if self.static else 0)
        return role, records, kw

    # -- what the subclass provides
    def start(self):
        """Both sides up (the receiving side first, so the sender finds it)."""
        raise NotImplementedError

    def stop(self):
        raise NotImplementedError

    def check(self):
        """Raise MatrixError when a participant died."""

    def clock(self):
        """Seconds (real or virtual)."""
        raise NotImplementedError

    def pause(self):
        """Let time go on until the next look."""
        raise NotImplementedError

    def restart_ours(self):
        raise NotImplementedError

    def restart_peer(self):
        raise NotImplementedError

    def plc_words(self):
        """Our PLC's peer block (%MW peer_base(1) .., W_BASE + WINDOW words)."""
        raise NotImplementedError

    def peer_received(self):
        """The peer's receiver (mippeer.cli.received of its current life)."""
        raise NotImplementedError

    def peer_seen(self, kind, number):
        """The peer's current life saw ("accepted" | "acknowledged", number)."""
        raise NotImplementedError

    def peer_acknowledged(self):
        raise NotImplementedError

    def lost_blocks(self):
        """Radio telegrams carrying a block that were lost (the emulator's trace)."""
        raise NotImplementedError

    def virtual_s(self):
        return None

    # -- the judge
    def plc_stream_state(self, w, want, resent):
        """Our receiver's committed stream against `want` (a list of records). `resent`: the
        stream's sender restarted in this cell, so the whole transfer may arrive again."""
        stream = [v for r in want for v in r]
        committed = w[L.R_COM_LO] + (w[L.R_COM_HI] << 16)
        window = w[L.W_BASE:]
        if committed == 0:
            return "pending", ""
        k, rest = divmod(committed, len(stream))
        if rest:
            return "bad", (f"our receiver committed {committed} registers: not whole transfers "
                           f"of the {len(stream)} sent")
        if k > 1 and not resent:
            return "bad", f"our receiver committed the transfer {k} times"
        full = stream * k
        # the ring positions an open transfer (e.g. the resend after a restart) has not
        # overwritten yet
        for p in L.committed_positions(w):
            if window[p % L.WINDOW] != full[p]:
                return "bad", (f"our receiver's committed register {p} (record "
                               f"{p % len(stream) // len(want[0]) + 1} of the transfer) is "
                               f"{window[p % L.WINDOW]}, {full[p]} was sent")
        if (w[L.R_SUM_A], w[L.R_SUM_B]) != L.fletcher(full):
            return "bad", "checksum of our receiver's committed stream differs"
        return "held", ""

    def peer_stream_state(self, got, want, resent):
        transfers = got.get("transfers", [])
        for t in transfers:
            if t != want:
                return "bad", (f"the peer completed a transfer of {len(t)} records that is not "
                               f"the {len(want)} sent")
        if len(transfers) > 1 and not resent:
            return "bad", f"the peer received the transfer {len(transfers)} times"
        return ("held", "") if transfers else ("pending", "")

    def observe(self):
        """(streams, errors, bad): per stream 'held'/'done'/'pending'; our failures so far."""
        w = self.plc_words()
        got = self.peer_received()
        streams, bad = {}, ""
        errors = []
        # up stream: outstation -> central
        if self.cell.ours == "sender":
            state, why = self.peer_stream_state(got, self.up_want(), self.ours_restarted)
            sender_done = w[L.S_ALL] == 1
        else:
            state, why = self.plc_stream_state(w, self.up_want(), self.peer_restarted)
            sender_done = self.peer_seen("acknowledged", 0xFFFF)
        streams["up"] = "complete" if state == "held" and sender_done else state
        bad = bad or why
        if self.bidi:
            if self.cell.ours == "sender":
                state, why = self.plc_stream_state(w, self.down_want(), self.peer_restarted)
                sender_done = self.peer_seen("acknowledged", 0xFFFF)
            else:
                state, why = self.peer_stream_state(got, self.down_want(), self.ours_restarted)
                sender_done = w[L.S_ALL] == 1
            streams["down"] = "complete" if state == "held" and sender_done else state
            bad = bad or why
        if w[L.S_FAILED]:
            errors.append(("sender", L.error_name(w[L.S_ERROR])))
        if w[L.R_FAILED] or w[L.R_ERROR]:
            # a failed transfer, or an error with nothing open (e.g. P21 out of step after
            # this side restarted): the central program shows the receiver's last error id
            errors.append(("receiver", L.error_name(w[L.R_ERROR])))
        return streams, errors, bad

    # -- the run
    def run(self) -> Result:
        t_begin = time.monotonic()
        cfg, cell = self.cfg, self.cell
        try:
            self.start()
            t0 = self.clock()
            cap = cfg.cap_loss_s if cell.fault == "loss30" else cfg.cap_s
            restart_pending = cell.fault.startswith("restart")
            first_error = None          # (seconds after t0, who, name)
            errors_seen = []
            streams = {}
            while True:
                self.check()
                now = self.clock()
                if restart_pending:
                    kind = "accepted" if cell.ours == "sender" else "acknowledged"
                    if self.peer_seen(kind, cfg.restart_after):
                        if cell.fault == "restart-ours":
                            self.ours_restarted = True
                            self.restart_ours()
                        else:
                            self.peer_restarted = True
                            self.restart_peer()
                        restart_pending = False
                        t0 = self.clock()
                        first_error, errors_seen = None, []
                        continue
                    if now - t0 > cap:
                        return self._result("FAIL", False, "no restart: record "
                                            f"{cfg.restart_after} was never acknowledged",
                                            streams, errors_seen, t_begin)
                streams, errors, bad = self.observe()
                if bad:
                    return self._result("FAIL", False, f"data wrong: {bad}", streams,
                                        errors, t_begin)
                for e in errors:
                    if e not in errors_seen:
                        errors_seen.append(e)
                        if first_error is None:
                            first_error = (round(now - t0, 2), e[0], e[1])
                if not restart_pending and all(s == "complete" for s in streams.values()):
                    text = "complete"
                    if errors_seen:
                        text += " after " + ", ".join(n for _, n in errors_seen)
                    return self._result("complete", True, text, streams, errors_seen, t_begin)
                if first_error is not None and not restart_pending:
                    t_err, who, name = first_error
                    if now - t0 >= t_err + cfg.bound_s or now - t0 > cap:
                        ok = t_err <= cfg.bound_s
                        text = f"error {name} after {t_err:.1f} s"
                        if not ok:
                            text += f" (bound {cfg.bound_s:g} s)"
                        r = self._result("error" if ok else "FAIL", ok, text, streams,
                                         errors_seen, t_begin)
                        r.error, r.error_after_s = name, t_err
                        return r
                if now - t0 > cap:
                    pending = ", ".join(f"{k} {v}" for k, v in streams.items())
                    return self._result("FAIL", False, f"hang: no completion and no error in "
                                        f"{cap:g} s ({pending})", streams, errors_seen, t_begin)
                self.pause()
        except self.FAILURES as e:
            raise MatrixError(f"{cell.key}: {e}") from None
        finally:
            self.stop()

    def _result(self, outcome, passed, text, streams, errors, t_begin):
        detail = ""
        try:
            w = self.plc_words()
            got = self.peer_received()
            detail = (f"ours: delivered {w[L.R_REC_LO]}, duplicates {w[L.R_DUP]}, unexpected "
                      f"{w[L.R_UNEXP]}, retransmissions {w[L.S_RETRANS]}, read out "
                      f"{w[L.S_OUT_LO]}; peer: accepted {got.get('accepted', [])}, "
                      f"duplicates {got.get('duplicates', 0)}, unexpected "
                      f"{got.get('unexpected', 0)}, acknowledged {self.peer_acknowledged()}")
        except Exception as e:     # the PLC may be gone; the detail is only a help
            detail = f"no counters: {e}"
        v = self.virtual_s()
        return Result(cell=self.cell.key, outcome=outcome, passed=passed, text=text,
                      errors=[f"{who}:{name}" for who, name in errors], streams=dict(streams),
                      seconds=round(time.monotonic() - t_begin, 1),
                      lost_telegrams=self.lost_blocks(), detail=detail,
                      virtual_s=None if v is None else round(v, 2))
