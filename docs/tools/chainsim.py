"""The MIP blocks of st_lib in two soft PLCs and the emulator core, run by the co-simulation
kernel (cosim/, libmipcosim) in one virtual time: the source of the traces behind the
documentation's pictures, the training tool mipsim and the blocks' chain tests.

Each side is one PLC program (docs/tools/chain_main.st) that calls MIP_Sender, MIP_Receiver
or MIP_Link, compiled by stc into the soft-PLC runtime (plcrt). Its Modbus requests are the
runtime's own: the master of each PLC has a read range (125 registers at the read-status
register) and a write range (at the first write register) in a config written here, with the
trigger policy (docs/dev/interfaces.md §4; the program raises a read every `read_ms` and a
write per rising edge of the block's xWriteReq) or, for `cyclic_ms`, the cyclic policy
(OpenPLC: both ranges every period, xReadValid always TRUE, a write done after
`cyclic_done_periods` periods of xWriteReq). The kernel's in-process transport hands the
requests to the emulator core. This driver only steps the kernel one scan tick at a time,
feeds the application's side (xExecute, the data to send) and watches.

The emulator's trace is kept as is; the driver adds lines with "ev":"plc" (what a PLC saw or
did) so the diagrams can say it in the application's words: a read that found new data and a
write (next to the emulator's line of that Modbus request, labelled from the PLC's image; a
pipelined sender's write of the next record says which record still waits for its
acknowledgement), a record delivered, a record the receiver ignored (neither the next one nor
a duplicate), a pipelined sender going back to an older record, xError, xDone (from the PLC's
variables after the scan), a restart.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from mipcosim import sim as _sim
from mipcosim.kernel import MS, CosimError, Kernel, Radio
from mipcosim.programs import LIB_FILES, st_enums   # import order, the one list
from mipprobe.regmap import MDP810, TRM810
from plcharness.config import Config

REPO = Path(__file__).resolve().parents[2]

PROGRAM = Path(__file__).with_name("chain_main.st")
# MIP_STLIB_DIR: take the blocks from another directory (e.g. an export of the last commit while
# st_lib/ has work in progress); default st_lib/ of this checkout.
LIB_DIR = Path(os.environ.get("MIP_STLIB_DIR") or REPO / "st_lib")
FFFF = 0xFFFF
ROLE = {"sender": 1, "receiver": 2, "link": 3}
FB = {1: "snd", 2: "rcv", 3: "lnk"}
READ_IMAGE = 100          # %IW100..%IW224: the read range (chain_main.st)
WRITE_IMAGE = 100         # %QW100..%QW222: the write range
# the emulator's defaults (mipemu_config_default): the realistic radio, 9600 bit/s
EMU_DEFAULTS = {"stations": 1, "mode": 0, "static_registers": 123, "loss_down": 0.0,
                "loss_up": 0.0, "burst": 0.0, "seed": 1, "bitrate": 9600,
                "slot_gap_ns": 20 * MS, "overhead_bytes": 12}



class ChainError(RuntimeError):
    """The PLC program could not be built or loaded, or the kernel refused something (one
    line, for the command line)."""


def build_plc(workdir: Path, config=None):
    """st_lib + the chain program, built once per process (sim.build caches it), loaded as a
    fresh PLC (its own library copy) with the runtime config `config`."""
    from plcharness import Plc
    from plcharness.build import BuildError
    from plcharness.plc import PlcError
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        result = _sim.build("docs-chain", False, workdir,
                            sources=[LIB_DIR / f for f in LIB_FILES] + [PROGRAM])
        return Plc(result, workdir, config=config)
    except BuildError as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else "build failed"
        raise ChainError(f"building st_lib + {PROGRAM.name} failed: {first}") from None
    except PlcError as e:           # the config or the library did not load
        raise ChainError(f"{PROGRAM.name}: {e}") from None


def plc_config(side) -> str:
    """The runtime config of one side: its modem as one device with a read and a write range
    (the device's host and port are never used: the kernel's in-process transport)."""
    central = side.name == "central"
    regs = MDP810 if central else TRM810
    rd, wr = regs.read_status, regs.write_data
    cfg = Config(comment=f"{side.name} of docs/tools/chainsim.py (written by it)")
    cfg.add("master", timeout="1s")
    if side.cyclic_ms:
        size = side.chunk                        # the fixed write range (the static length)
        pol_r = pol_w = {"policy": "cycle"}
    else:
        size = 123
        pol_r = {"policy": "trigger", "trigger": "%QX1.0", "done": "%IX1.0", "error": "%IX1.1"}
        pol_w = {"policy": "trigger", "trigger": "%QX1.1", "done": "%IX1.2", "error": "%IX1.3",
                 "length": "%QW1"}
    cfg.add("device", "modem", host="127.0.0.1", port=502, unit_id=1,
            polling_period=f"{side.cyclic_ms}ms" if side.cyclic_ms else None)
    cfg.add("read", "modem_read", device="modem", start=rd, size=125, image=f"%IW{READ_IMAGE}",
            **pol_r)
    cfg.add("write", "modem_write", device="modem", start=wr, size=size,
            image=f"%QW{WRITE_IMAGE}", **pol_w)
    return cfg.text()


@dataclass
class Side:
    """One PLC with its modem endpoint."""
    name: str                  # "outstation" or "central"
    role: str                  # sender / receiver / link
    data: list = field(default_factory=list)   # what a sending side sends (registers)
    polled: bool = False
    timeout_ms: int = 2000
    chunk: int = 123
    read_ms: int = 100         # trigger policy: a read every read_ms (>= 20: a level handshake)
    read_phase_ms: int = 0     # the PLC starts (its first scan, its first read) at this time
    start_ms: int = 0          # xExecute rises at this time (sending sides)
    static: bool = False       # static MIP mode (xStatic; the modems must be static too)
    cyclic_ms: int = 0         # > 0: OpenPLC-style master (cyclic policy): read and write every
                               # cyclic_ms, xReadValid always TRUE, a write "done" after
    cyclic_done_periods: float = 1.5   # ... this many periods of xWriteReq
    window: int = 1            # a sender's uWindow: 1 stop and wait, 2 pipelined (PROTOCOL.md P27)

    def attach(self, plc):
        """A fresh program instance for this side (the first or after a restart)."""
        self.plc = plc
        self.fb = FB[ROLE[self.role]]
        p = plc
        p["MAIN.role"] = ROLE[self.role]
        p["MAIN.central"] = self.name == "central"
        p["MAIN.polled"] = self.polled
        p["MAIN.static"] = self.static
        p["MAIN.tmo"] = self.timeout_ms * MS
        p["MAIN.chunkSize"] = self.chunk
        p["MAIN.window"] = self.window
        p["MAIN.readEvery"] = self.read_ms * MS
        p["MAIN.cyclic"] = bool(self.cyclic_ms)
        p["MAIN.cyclicDone"] = int(self.cyclic_done_periods * self.cyclic_ms * MS)
        p["MAIN.enable"] = self.role in ("receiver", "link")
        self.ep = "mdp" if self.name == "central" else "trm"
        self.received: list[tuple[int, list]] = []
        self.transfers: list[list] = []
        self.errors: list[str] = []
        self._cur: list = []
        self._last_err = False
        self._last_done = False
        self._unexpected = 0      # the receiver's udiUnexpected after the last scan
        self._retrans = 0         # the sender's udiRetransmissions after the last scan
        self._last_rec = 0        # the record number of the sender's last write
        self._retry_at = None
        # the write range as the last scan left it (the master writes it in the next I/O
        # phase); the modem's write area starts at 0
        self._out = [0] * (self.chunk if self.cyclic_ms else 2)
        self._last_written = [0] * self.chunk

    def fbv(self, member):
        return self.plc[f"MAIN.{self.fb}.{member}"]

    def before_scan(self, t_ns):
        """The application's inputs for the scan at t_ns."""
        p = self.plc
        if self.role in ("sender", "link") and self.data:
            p["MAIN.execute"] = self.execute(t_ns // MS)
            if self.fbv("xChunkRequest"):
                idx, cmax = self.fbv("udiChunkIndex"), self.fbv("uChunkMax")
                part = self.data[idx * cmax:(idx + 1) * cmax]
                p["MAIN.chunk"] = part + [0] * (122 - len(part))
                p["MAIN.chunkLen"] = len(part)
                p["MAIN.chunkLast"] = (idx + 1) * cmax >= len(self.data)
                p["MAIN.chunkValid"] = True
            else:
                p["MAIN.chunkValid"] = False

    def execute(self, t_ms):
        """xExecute: TRUE from start_ms on; after an error FALSE for one read period, then
        TRUE again (an operator or a sequence retrying the transfer)."""
        if t_ms < self.start_ms:
            return False
        if self._retry_at is not None and t_ms < self._retry_at:
            return False
        return True

    def label(self, header, peer=False):
        """Counter registers in the application's words (peer: of a block the peer wrote)."""
        if self.role == "link":
            return f"[{header[0]} | {header[1] if len(header) > 1 else '-'}]"
        if not header:
            return "(empty)"
        word = "record" if (self.role == "sender") != peer else "ack"
        return f"{word} {header[0]}"

    def request(self, line):
        """plc lines for one of this side's Modbus requests in the emulator's trace:
        (before, after) the request's line."""
        t = line["t"]
        if line.get("fc") == 3 and not line.get("exc"):
            p = self.plc
            regs = [p[f"%IW{READ_IMAGE + i}"] for i in range(4)]   # what the read brought
            if regs[0] & 1 and regs[1] >= 1:
                what = self.label(regs[2:2 + min(regs[1], 2)], True)
                if self.cyclic_ms and self.role != "link" and not any(
                        p[f"%IW{READ_IMAGE + 2 + i}"] for i in range(min(regs[1], 123))):
                    what = "zeros"          # a static block of zeros: a sender's idle block
                return [], [self._line(t, "read", f"read: new data, {what}", regs[2])]
        elif line.get("fc") == 16:
            n = line.get("wq", 0)
            hdr = self._out[:2 if self.role == "link" else 1]
            if self.role == "sender" and not line.get("exc"):
                self._last_rec = hdr[0]
            regs = "1 reg" if n == 1 else f"{n} regs"
            same = ahead = ""
            what = self.label(hdr)
            if self.role == "sender" and 0 < self.fbv("wRecord") < hdr[0]:
                # the pipelined sender (P27) writes the next record while wRecord waits
                ahead = f", before ack {self.fbv('wRecord')}"
            if self.cyclic_ms:
                block = self._out[:n]
                same = ", unchanged" if block == self._last_written[:n] else ""
                self._last_written = block
                if not any(block) and self.role != "link":
                    what = "zeros"      # the image before the first scan, a sender's idle block
            return [self._line(t, "write", f"write {what} ({regs}{same}){ahead}", hdr)], []
        return [], []

    def after_scan(self, t_ns):
        """plc lines from the program's state after its scan at t_ns."""
        out = []
        if self.role in ("receiver", "link") and self.fbv("xRecordValid"):
            num, n = self.fbv("wRecordNumber"), self.fbv("uRecordLen")
            payload = self.fbv("aRecord")[:n]
            self.received.append((num, payload))
            if num == 1:
                self._cur = []
            self._cur += payload
            out.append(self._line(t_ns, "deliver", f"record {num} delivered ({n} regs)", num))
            if num == FFFF:
                self.transfers.append(self._cur)
                self._cur = []
        if self.role == "receiver":
            # a record that is neither the next one nor a duplicate: ignored (P20), e.g. a
            # pipelined record that overwrote the one before it in the modem (P27)
            unexpected = self.fbv("udiUnexpected")
            if unexpected > self._unexpected:
                num, ack = self.plc[f"%IW{READ_IMAGE + 2}"], self.fbv("wAck")
                nxt = 1 if ack in (0, FFFF) else ack + 1
                out.append(self._line(t_ns, "ignore", f"record {num} ignored: not the next one "
                                      f"({nxt})", num))
            self._unexpected = unexpected
        if self.role == "sender":
            # a retransmission that goes back to an older record: the pipelined sender closes
            # its window (P27); a repeat of the record last written is not marked
            retrans = self.fbv("udiRetransmissions")
            rec = self.fbv("wRecord")
            if retrans > self._retrans and 0 < rec < self._last_rec:
                out.append(self._line(t_ns, "goback", f"no ack within tTimeout: back to record "
                                      f"{rec}, window closed", rec))
            self._retrans = retrans
        err = self.fbv("xError") if self.role != "link" else (
            self.fbv("xSendError") or self.fbv("xRecvError"))
        if err and not self._last_err:
            eid = self.fbv("eErrorId") if self.role != "link" else max(
                self.fbv("eSendErrorId"), self.fbv("eRecvErrorId"))
            self.errors.append(ERRORS[eid])
            out.append(self._line(t_ns, "error", f"xError: {ERRORS[eid]}", eid))
            if self.role in ("sender", "link") and self.data:
                self._retry_at = t_ns // MS + self.read_ms
        self._last_err = err
        done = self.fbv("xDone") if self.role == "sender" else (
            self.fbv("xSendDone") if self.role == "link" else False)
        if done and not self._last_done:
            out.append(self._line(t_ns, "done", "xDone: last record acknowledged", 1))
        self._last_done = done
        # what the master will write in the next I/O phase
        self._out = [self.plc[f"%QW{WRITE_IMAGE + i}"] for i in range(len(self._out))]
        return out

    def _line(self, t_ns, what, text, value):
        return {"t": t_ns, "ev": "plc", "side": self.name, "what": what, "text": text,
                "value": value}

    @property
    def send_done(self):
        if getattr(self, "plc", None) is None:
            return self.role == "receiver"
        if self.role == "sender":
            return bool(self.fbv("xDone"))
        if self.role == "link":
            return bool(self.fbv("xSendDone"))
        return True


ERRORS = st_enums(LIB_DIR / "core" / "MIP_Types.st")["E_MIP_Error"]   # names by number, from the ST


class Chain:
    """Outstation PLC -- TRM-810 ~~radio~~ MDP-810 -- central PLC in the co-simulation kernel,
    stepped one scan tick (tick_ms) at a time. emu: the emulator's configuration (keys of
    EMU_DEFAULTS; slot_gap_ms for slot_gap_ns). outstation or central may be None (a test
    that brings its own PLC: add_plc)."""

    def __init__(self, workdir: Path, outstation: Side | None, central: Side | None,
                 tick_ms=10, **emu):
        if tick_ms != 10:
            raise ChainError("tick_ms: chain_main.st's task runs every 10 ms")
        cfg = dict(EMU_DEFAULTS)
        for k, v in emu.items():
            if k == "slot_gap_ms":
                k, v = "slot_gap_ns", int(v * MS)
            if k not in cfg:
                raise ChainError(f"emulator option {k!r}: use one of {', '.join(cfg)}")
            cfg[k] = v
        self.workdir = Path(workdir)
        self.tick = tick_ms * MS
        self.sides = [s for s in (outstation, central) if s is not None]
        try:
            self.kernel = Kernel(cfg["stations"], static=bool(cfg["mode"]),
                                 static_registers=cfg["static_registers"],
                                 loss_down=cfg["loss_down"], loss_up=cfg["loss_up"],
                                 burst=cfg["burst"], seed=cfg["seed"],
                                 radio=Radio(cfg["bitrate"], cfg["slot_gap_ns"],
                                             cfg["overhead_bytes"]), error=ChainError)
        except CosimError as e:
            raise ChainError(str(e)) from None
        self._batch: list[dict] = []      # the emulator's lines of the current step
        self.kernel.on_trace(self._batch_line)
        self.lines: list[dict] = []       # the merged trace so far
        self.ids = {}                     # side name -> kernel PLC id
        self.plcs = []                    # every PLC instance loaded (closed at the end)
        self.confs = {}
        for s in self.sides:
            self.confs[s.name] = self.workdir / f"chain-{s.name}{'-cyclic' if s.cyclic_ms else ''}.conf"
            self.workdir.mkdir(parents=True, exist_ok=True)
            self.confs[s.name].write_text(plc_config(s))
            s.plc, s.received, s.transfers, s.errors = None, [], [], []
            self._start(s)

    def _batch_line(self, line):
        self._batch.append(line)

    @property
    def t(self):
        """Virtual time of the next scan."""
        return self.kernel.now

    def _start(self, side: Side):
        """A fresh program instance for side, wired to its modem; the first scan at
        read_phase_ms (the first start) or now (a restart)."""
        if side.name not in self.ids and self.t < side.read_phase_ms * MS:
            side.plc = None                     # not started yet: step() starts it
            return
        plc = build_plc(self.workdir, self.confs[side.name])
        self.plcs.append(plc)
        side.attach(plc)
        if side.name in self.ids:
            self.kernel.replace(self.ids[side.name], plc, self.tick, name=side.name)
        else:
            self.ids[side.name] = self.kernel.add_plc(plc, self.tick, name=side.name)
        self.kernel.connect(self.ids[side.name], plc, "modem", 0 if side.name == "central" else 1)

    def add_plc(self, plc):
        """Another PLC (a plcharness Plc) scanned in the same lockstep from now on, every tick;
        the caller serves its I/O between steps (e.g. a program without the runtime's master)."""
        self.plcs.append(plc)
        return self.kernel.add_plc(plc, self.tick)

    def _emit(self, line):
        self.lines.append(line)

    def restart(self, side: Side):
        """A PLC restart: a fresh program instance (all state lost) from the next scan on;
        the modems keep theirs."""
        self._emit(side._line(self.t, "restart", "PLC restarted", 0))
        self._start(side)

    def step(self):
        """One scan tick: every PLC due scans once at t (its I/O phase first: the master's
        requests go to the emulator core), the radio runs on to t + tick."""
        t = self.t
        for s in self.sides:
            if s.plc is None and t >= s.read_phase_ms * MS:
                self._start(s)
        live = [s for s in self.sides if s.plc is not None]
        for s in live:
            s.before_scan(t)
        self._batch = []
        self.kernel.run_until(t + self.tick)
        # the emulator's lines of this step, each request with the plc lines of its PLC,
        # then what the scans left (after every line up to t: the radio's later ones follow)
        by_ep = {s.ep: s for s in live}
        merged = []
        for d in self._batch:
            side = by_ep.get(d.get("ep")) if d.get("ev") == "modbus" and d.get("st") == 1 else None
            before, after = side.request(d) if side else ([], [])
            merged += before + [d] + after
        cut = len(merged)
        while cut and merged[cut - 1]["t"] > t:
            cut -= 1
        scanned = [line for s in live for line in s.after_scan(t)]
        self.lines += merged[:cut] + scanned + merged[cut:]

    def run_until(self, cond, limit_ms):
        end = self.t + limit_ms * MS
        while self.t < end:
            if cond():
                return True
            self.step()
        return cond()

    def stats(self, station=1):
        """The emulator's radio counters of `station`."""
        return self.kernel.radio_stats([station])

    def trace(self) -> list[str]:
        """The emulator's lines with the plc lines merged in, numbered."""
        out = []
        for seq, d in enumerate(self.lines):
            d = dict(d)
            d["seq"] = seq
            keys = ["t", "seq"] + [k for k in d if k not in ("t", "seq")]
            out.append(json.dumps({k: d[k] for k in keys}, separators=(",", ":")))
        return out

    def close(self):
        self.kernel.close()
        for p in self.plcs:
            p.close()
        self.plcs = []
