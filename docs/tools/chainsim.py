"""The MIP blocks of st_lib, running in two soft PLCs (plcharness), against the emulator core,
all in one virtual time: the source of the traces behind the documentation's pictures.

Each side is one PLC program (docs/tools/chain_main.st) that calls MIP_Sender, MIP_Receiver
or MIP_Link. This driver plays the runtime's trigger policy (docs/dev/interfaces.md §4): a
125-register FC3 read at the read-status register every `read_ms`, valid for one scan; one
FC16 write of aWrite[0..uWriteLen-1] per rising edge of xWriteReq, answered with xWriteDone in
the next scan. The emulator's trace is kept as is; the driver adds lines with "ev":"plc"
(what a PLC saw or did) so the diagrams can say it in the application's words.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from mipemu_ctypes import Net

REPO = Path(__file__).resolve().parents[2]
from mipcosim.layout import LIB_FILES   # import order, the one list
PROGRAM = Path(__file__).with_name("chain_main.st")
# MIP_STLIB_DIR: take the blocks from another directory (e.g. an export of the last commit while
# st_lib/ has work in progress); default st_lib/ of this checkout.
LIB_DIR = Path(os.environ.get("MIP_STLIB_DIR") or REPO / "st_lib")
MS = 1_000_000
FFFF = 0xFFFF
ROLE = {"sender": 1, "receiver": 2, "link": 3}
FB = {1: "snd", 2: "rcv", 3: "lnk"}

_BUILD = {}


class ChainError(RuntimeError):
    """The PLC program could not be built or loaded (one line, for the command line)."""


def build_plc(workdir: Path):
    """Builds st_lib + the chain program once per process, then loads a fresh PLC each call."""
    from plcharness import Plc
    from plcharness.build import BuildError
    key = str(workdir)
    if key not in _BUILD:
        workdir.mkdir(parents=True, exist_ok=True)
        try:
            plc = Plc.build([str(LIB_DIR / f) for f in LIB_FILES] + [str(PROGRAM)],
                            workdir=workdir, compiler="stc")
        except BuildError as e:
            first = str(e).strip().splitlines()[0] if str(e).strip() else "build failed"
            raise ChainError(f"building st_lib + {PROGRAM.name} failed: {first}") from None
        _BUILD[key] = plc.build_result
        return plc
    return Plc(_BUILD[key], workdir)


@dataclass
class Side:
    """One PLC with its modem endpoint."""
    name: str                  # "outstation" or "central"
    role: str                  # sender / receiver / link
    data: list = field(default_factory=list)   # what a sending side sends (registers)
    polled: bool = False
    timeout_ms: int = 2000
    chunk: int = 123
    read_ms: int = 100
    read_phase_ms: int = 0
    start_ms: int = 0          # xExecute rises at this time (sending sides)
    static: bool = False       # static MIP mode (xStatic; the modems must be static too)
    cyclic_ms: int = 0         # > 0: OpenPLC-style master: read and write every cyclic_ms,
                               # xReadValid always TRUE, a write "done" after
    cyclic_done_periods: float = 1.5   # ... this many periods of xWriteReq

    def attach(self, plc, net: Net, emit):
        self.plc, self.net, self.emit = plc, net, emit
        central = self.name == "central"
        self.ep, self.unit = (0, 1) if central else (1, 1)
        self.rd_addr, self.wr_addr = (198, 10) if central else (2198, 2001)
        self.fb = FB[ROLE[self.role]]
        p = plc
        p["MAIN.role"] = ROLE[self.role]
        p["MAIN.central"] = central
        p["MAIN.polled"] = self.polled
        p["MAIN.static"] = self.static
        self._req_since = None
        self._last_cyclic = None
        p["MAIN.tmo"] = self.timeout_ms * MS
        p["MAIN.chunkSize"] = self.chunk
        self.wr_done = False
        self.received: list[tuple[int, list]] = []
        self.transfers: list[list] = []
        self._cur: list = []
        self.errors: list[str] = []
        self._last_err = False
        self._last_done = False
        self._retry_at = None

    def fbv(self, member):
        return self.plc[f"MAIN.{self.fb}.{member}"]

    def before_scan(self, t_ns):
        p = self.plc
        t_ms = t_ns // MS
        period = self.cyclic_ms or self.read_ms
        if (t_ms - self.read_phase_ms) % period == 0:
            regs, exc = self.net.read(self.ep, self.unit, self.rd_addr, 125)
            p["MAIN.rd"] = regs
            p["MAIN.rdValid"] = True
            if regs[0] & 1 and regs[1] >= 1:
                self.emit(t_ns, self.name, "read",
                          f"read: new data, {self.label(regs[2:2 + min(regs[1], 2)], True)}",
                          regs[2])
        else:
            p["MAIN.rdValid"] = bool(self.cyclic_ms)
        if self.role in ("sender", "link") and self.data:
            p["MAIN.execute"] = self.execute(t_ms)
            if self.fbv("xChunkRequest"):
                idx, cmax = self.fbv("udiChunkIndex"), self.fbv("uChunkMax")
                part = self.data[idx * cmax:(idx + 1) * cmax]
                p["MAIN.chunk"] = part + [0] * (122 - len(part))
                p["MAIN.chunkLen"] = len(part)
                p["MAIN.chunkLast"] = (idx + 1) * cmax >= len(self.data)
                p["MAIN.chunkValid"] = True
            else:
                p["MAIN.chunkValid"] = False
        p["MAIN.enable"] = self.role in ("receiver", "link")

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

    def after_scan(self, t_ns):
        p = self.plc
        if self.role in ("receiver", "link") and self.fbv("xRecordValid"):
            num, n = self.fbv("wRecordNumber"), self.fbv("uRecordLen")
            payload = self.fbv("aRecord")[:n]
            self.received.append((num, payload))
            if num == 1:
                self._cur = []
            self._cur += payload
            self.emit(t_ns, self.name, "deliver", f"record {num} delivered ({n} regs)", num)
            if num == FFFF:
                self.transfers.append(self._cur)
                self._cur = []
        err = self.fbv("xError") if self.role != "link" else (
            self.fbv("xSendError") or self.fbv("xRecvError"))
        if err and not self._last_err:
            eid = self.fbv("eErrorId") if self.role != "link" else max(
                self.fbv("eSendErrorId"), self.fbv("eRecvErrorId"))
            self.errors.append(ERRORS[eid])
            self.emit(t_ns, self.name, "error", f"xError: {ERRORS[eid]}", eid)
            if self.role in ("sender", "link") and self.data:
                self._retry_at = t_ns // MS + self.read_ms
        self._last_err = err
        done = self.fbv("xDone") if self.role == "sender" else (
            self.fbv("xSendDone") if self.role == "link" else False)
        if done and not self._last_done:
            self.emit(t_ns, self.name, "done", "xDone: last record acknowledged", 1)
        self._last_done = done
        if self.cyclic_ms:
            self._cyclic_write(t_ns)
            return
        if self.fbv("xWriteReq"):
            if not self.wr_done:
                n = self.fbv("uWriteLen")
                block = self.fbv("aWrite")[:n]
                hdr = block[:2 if self.role == "link" else 1]
                regs = "1 reg" if n == 1 else f"{n} regs"
                self.emit(t_ns, self.name, "write", f"write {self.label(hdr)} ({regs})", hdr)
                exc = self.net.write(self.ep, self.unit, self.wr_addr, block)
                self.wr_done = True
                p["MAIN.wrDone"] = exc == 0
                p["MAIN.wrError"] = exc != 0
        elif self.wr_done:
            self.wr_done = False
            p["MAIN.wrDone"] = False
            p["MAIN.wrError"] = False

    def _cyclic_write(self, t_ns):
        """OpenPLC's master: the write range is written every period, whatever it holds; the
        program counts a request as done when it has been up for cyclic_done_periods."""
        p = self.plc
        t_ms = t_ns // MS
        n = self.chunk                      # the fixed write range (the static length)
        block = self.fbv("aWrite")[:n]
        if (t_ms - self.read_phase_ms) % self.cyclic_ms == self.cyclic_ms // 2:
            hdr = block[:2 if self.role == "link" else 1]
            last = self._last_cyclic if self._last_cyclic is not None else [0] * n  # modem starts at 0
            same = ", unchanged" if block == last else ""
            self.emit(t_ns, self.name, "write", f"write {self.label(hdr)} ({n} regs{same})", hdr)
            self.net.write(self.ep, self.unit, self.wr_addr, block)
            self._last_cyclic = block
        if self.fbv("xWriteReq"):
            if self._req_since is None:
                self._req_since = t_ns
            done = t_ns - self._req_since >= self.cyclic_done_periods * self.cyclic_ms * MS
        else:
            self._req_since = None
            done = False
        p["MAIN.wrDone"] = done
        p["MAIN.wrError"] = False

    @property
    def send_done(self):
        if self.role == "sender":
            return bool(self.fbv("xDone"))
        if self.role == "link":
            return bool(self.fbv("xSendDone"))
        return True


ERRORS = ["MIP_ERR_NONE", "MIP_ERR_CHUNK_SIZE", "MIP_ERR_CHUNK_LEN", "MIP_ERR_NO_ACK",
          "MIP_ERR_PEER_RESET", "MIP_ERR_TOO_MANY_RECORDS", "MIP_ERR_ABORTED",
          "MIP_ERR_SENDER_RESET", "MIP_ERR_TRANSFER_TIMEOUT", "MIP_ERR_BUFFER_LEN"]


class Chain:
    """Outstation PLC -- TRM-810 ~~radio~~ MDP-810 -- central PLC, stepped every tick_ms."""

    def __init__(self, workdir: Path, outstation: Side, central: Side, tick_ms=10, **emu):
        self.plc_lines: list[tuple[int, dict]] = []
        self.workdir = workdir
        self.net = Net(stations=1, **emu)
        self.sides = [outstation, central]
        self.tick = tick_ms * MS
        self.t = 0
        for s in self.sides:
            s.attach(build_plc(workdir), self.net, self._emit)

    def _emit(self, t_ns, side, what, text, value):
        self.plc_lines.append((len(self.net.lines), {"t": t_ns, "ev": "plc", "side": side,
                                                     "what": what, "text": text,
                                                     "value": value}))

    def restart(self, side: Side):
        """A PLC restart: a fresh program instance (all state lost); the modems keep theirs."""
        self._emit(self.t, side.name, "restart", "PLC restarted", 0)
        side.attach(build_plc(self.workdir), self.net, self._emit)

    def step(self):
        self.net.advance(self.t)
        for s in self.sides:
            s.before_scan(self.t)
        for s in self.sides:
            s.plc.scan()
        for s in self.sides:
            s.after_scan(self.t)
        self.t += self.tick

    def run_until(self, cond, limit_ms):
        end = self.t + limit_ms * MS
        while self.t < end:
            if cond():
                return True
            self.step()
        return cond()

    def trace(self) -> list[str]:
        """The emulator's lines with the driver's plc lines merged in time order, renumbered."""
        items = []
        for i, line in enumerate(self.net.lines):
            items.append((i, 1, i, json.loads(line)))
        for i, (pos, d) in enumerate(self.plc_lines):
            items.append((pos, 0, i, dict(d)))
        items.sort(key=lambda x: x[:3])
        out = []
        for seq, (_, _, _, d) in enumerate(items):
            d["seq"] = seq
            keys = ["t", "seq"] + [k for k in d if k not in ("t", "seq")]
            out.append(json.dumps({k: d[k] for k in keys}, separators=(",", ":")))
        return out

    def close(self):
        self.net.close()
