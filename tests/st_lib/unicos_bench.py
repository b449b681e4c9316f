"""Test bench for MIP_UnicosEvents: a generated test PROGRAM around the block, the record source
a MIP_Receiver with xAckByCaller would be (one record offered until xRecordProcessed), and the
PLC's Modbus client with its trigger-policy FC16 writes, whose requests go, as Modbus TCP frames,
to the independent WinCC OA stand-in (peers/mippeer/unicos.py) in virtual time.

The program mirrors every array as plain WORD variables (rec0.., a0.., b0..): matiec's
VARIABLES.csv does not list arrays (tests/st_lib/stlib_sim.py does the same)."""
from __future__ import annotations

import struct
from pathlib import Path

from mipcosim.programs import enum_values
from mippeer.unicos import UnicosDriver
import stlib_sim
from stlib_sim import LIB, MS, Fb, RunUntil
from plcharness import Plc

UERR = enum_values("E_MIP_ChainError", LIB / "chain" / "MIP_TypesSoe.st")
USTATE = enum_values("E_MIP_UnicosState", LIB / "chain" / "MIP_UnicosTypes.st")
SSTATE = enum_values("E_MIP_UnicosStatusState", LIB / "chain" / "MIP_UnicosTypes.st")
WAIT = enum_values("E_MIP_ChainWaitReason", LIB / "chain" / "MIP_TypesSoe.st")
TICK_MS = 10


def gen_program():
    """One program for every test of the hand-over (one build): `uni` fed by the bench's record
    source, and stlib_sim's `snd` and `rcv` with `cuni` after `rcv` (fed by it, feeding its
    xRecordProcessed: the chain's central); a PLC instance uses the part its test drives."""
    text = stlib_sim.gen_program([("snd", "MIP_Sender"), ("rcv", "MIP_Receiver")], TICK_MS)
    decl = ["  uni : MIP_UnicosEvents;", f"  rec : {stlib_sim.lib_type('MIP_T_Payload')};",
            "  " + ", ".join(f"rec{i}" for i in range(122)) + " : WORD;",
            "  " + ", ".join(f"a{i}" for i in range(123)) + " : WORD;",
            "  " + ", ".join(f"b{i}" for i in range(123)) + " : WORD;",
            "  cuni : MIP_UnicosEvents;",
            "  " + ", ".join(f"ua{i}" for i in range(123)) + " : WORD;",
            "  sts : MIP_UnicosStatus;", f"  tab : {stlib_sim.lib_type('MIP_T_UnicosTable')};",
            "  " + ", ".join(f"tab{i}" for i in range(96)) + " : WORD;",
            "  " + ", ".join(f"sa{i}" for i in range(98)) + " : WORD;",
            "  " + ", ".join(f"sb{i}" for i in range(98)) + " : WORD;"]
    text = text.replace("END_VAR\n", "\n".join(decl) + "\nEND_VAR\n", 1)
    call = "rcv(aRead := rcv_rd);\n"
    assert call in text
    calls = [f"rec[{i}] := rec{i};" for i in range(122)] + [
        "uni(aRecord := rec);",
        "cuni(aRecord := rcv.aRecord, uRecordLen := rcv.uRecordLen, xRecordValid := rcv.xRecordValid);",
        "rcv.xRecordProcessed := cuni.xRecordProcessed;"] + [
        f"tab[{i}] := tab{i};" for i in range(96)] + ["sts(aTable := tab);"]
    text = text.replace(call, call + "\n".join(calls) + "\n", 1)
    post = [f"a{i} := uni.stRequestA.aWrite[{i}];" for i in range(123)]
    post += [f"b{i} := uni.stRequestB.aWrite[{i}];" for i in range(123)]
    post += [f"ua{i} := cuni.stRequestA.aWrite[{i}];" for i in range(123)]
    post += [f"sa{i} := sts.stRequestA.aWrite[{i}];" for i in range(98)]
    post += [f"sb{i} := sts.stRequestB.aWrite[{i}];" for i in range(98)]
    return text.replace("END_PROGRAM", "\n".join(post) + "\nEND_PROGRAM", 1)


def build(workdir: Path) -> Plc:
    """The hand-over program: built once per compiler, a fresh PLC instance per call."""
    return stlib_sim.build_text(gen_program(), workdir, "unicos")


def entry(type_bit, address, cause, value, ts_ms):
    """One relay entry of 8 registers (docs/chain.md's relay facts): time stamp most
    significant register first."""
    return [type_bit, address, cause, value] + [(ts_ms >> s) & 0xFFFF for s in (48, 32, 16, 0)]


class Client:
    """The PLC's Modbus client for one driver: on stRequest<X>.xWriteReq it sends one FC16 of
    its uWriteLen registers at wWriteAddress to `driver` (a UnicosDriver, called directly); done on a normal
    answer, error with the exception code, or error with status 1110 (plcrt: timed out) after `timeout_scans` when
    the driver does not answer (muted, or `down`)."""

    def __init__(self, bench, ch, driver, timeout_scans=20, fb=None, reg=None, delay_scans=0):
        self.b, self.ch, self.driver = bench, ch, driver
        self.delay_scans = delay_scans               # an answer comes this many scans later
        self.fb = fb or bench.u                      # the block's members
        self.reg = reg or (lambda i: bench.plc[f"MAIN.{ch.lower()}{i}"])   # stRequest<ch>.aWrite[i]
        self.timeout_scans = timeout_scans
        self.down = False
        self.adus = []              # every request sent
        self._state, self._wait = "idle", 0
        self._tid = 0

    def _set(self, done, err, status=0):
        u = self.fb
        u[f"stReply{self.ch}.xWriteDone"], u[f"stReply{self.ch}.xWriteError"] = done, err
        u[f"stReply{self.ch}.wWriteStatus"] = status

    def after_scan(self):
        u = self.fb
        req = u[f"stRequest{self.ch}.xWriteReq"]
        if not req:
            if self._state != "idle":
                self._set(False, False)
            self._state = "idle"
            return
        if self._state == "idle":
            n = u[f"stRequest{self.ch}.uWriteLen"]
            regs = [self.reg(i) for i in range(n)]
            self._tid = (self._tid + 1) & 0xFFFF
            pdu = struct.pack(f">BHHB{n}H", 16, u["wWriteAddress"], n, 2 * n, *regs)
            adu = struct.pack(">HHHB", self._tid, 0, len(pdu) + 1, 1) + pdu
            self.adus.append(adu)
            self._resp = None if self.down else self.driver.handle(adu)
            self._state, self._wait = "waiting", 0
        elif self._state == "waiting":
            self._wait += 1
        if self._state == "waiting":
            resp = self._resp
            if resp is None:
                if self._wait >= self.timeout_scans:
                    self._state = "answered"
                    self._set(False, True, 1110)     # plcrt: 1000 + ETIMEDOUT
            elif self._wait >= self.delay_scans:
                self._state = "answered"
                if resp[7] & 0x80:
                    self._set(False, True, resp[8])
                else:
                    self._set(True, False)


class Source:
    """What MIP_Receiver (xAckByCaller) does: offers the next record until xRecordProcessed,
    then drops it for one scan. Notes the scan each record was offered and processed."""

    def __init__(self, bench):
        self.b = bench
        self.queue, self.offered, self.processed = [], [], []
        self._cur = None
        self._gap = False

    def before_scan(self):
        u, plc = self.b.u, self.b.plc
        if self._cur is None and self.queue and not self._gap:
            self._cur = self.queue.pop(0)
            for i in range(122):
                plc[f"MAIN.rec{i}"] = self._cur[i] if i < len(self._cur) else 0
            u["uRecordLen"] = len(self._cur)
            u["xRecordValid"] = True
            self.offered.append(self.b.scans)
        self._gap = False

    def after_scan(self):
        u = self.b.u
        if self._cur is not None and u["xRecordProcessed"]:
            self.processed.append(self.b.scans)
            self._cur = None
            u["xRecordValid"] = False
            self._gap = True


class UnicosBench(RunUntil):
    """One PLC with MIP_UnicosEvents `u`, the stand-in drivers `da` (A) and `db` (B) with
    their clients `ca` and `cb`, and the record source `src`."""

    def __init__(self, workdir, cfg=None, **settings):
        self.plc = build(workdir)
        self.u = Fb(self.plc, "uni")
        self.scans = 0
        self.da, self.db = UnicosDriver("A", cfg), UnicosDriver("B", cfg)
        self.ca, self.cb = Client(self, "A", self.da), Client(self, "B", self.db)
        self.src = Source(self)
        self.u["xEnable"] = True
        for k, v in settings.items():
            self.u[k] = v * MS if k.startswith("t") else v

    def step(self, n=1):
        for _ in range(n):
            self.src.before_scan()
            self.plc.scan()
            self.scans += 1
            self.ca.after_scan()
            self.cb.after_scan()
            self.src.after_scan()
            assert not (self.u["xBusy"] and self.u["xError"])

    def offer(self, *records):
        self.src.queue += [list(r) for r in records]

    def drain(self, limit=2000):
        ok = self.run_until(lambda: not self.src.queue and self.src._cur is None, limit)
        assert ok, f"records not all processed after {limit} scans: state {self.u['eState']}, " \
                   f"error {self.u['eErrorId']}"


class StatusBench:
    """One PLC with MIP_UnicosStatus `s` (its table set by `set_table`), the stand-in drivers
    `da`, `db` and their clients `ca`, `cb`."""

    def __init__(self, workdir, cfg=None, **settings):
        self.plc = build(workdir)
        self.scans = 0
        self.s = Fb(self.plc, "sts")
        self.da, self.db = UnicosDriver("A", cfg), UnicosDriver("B", cfg)
        self.ca = Client(self, "A", self.da, fb=self.s, reg=lambda i: self.plc[f"MAIN.sa{i}"])
        self.cb = Client(self, "B", self.db, fb=self.s, reg=lambda i: self.plc[f"MAIN.sb{i}"])
        self.s["xEnable"] = True
        for k, v in settings.items():
            self.s[k] = v * MS if k.startswith("t") else v

    def set_table(self, words):
        for i, w in enumerate(words):
            self.plc[f"MAIN.tab{i}"] = w

    def step(self, n=1):
        for _ in range(n):
            self.plc.scan()
            self.scans += 1
            self.ca.after_scan()
            self.cb.after_scan()
