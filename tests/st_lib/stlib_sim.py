"""Test bench for st_lib: a generated test PROGRAM around the MIP blocks, the runtime's side of
each block in Python (the Modbus client with its trigger policy and scriptable write failures,
the chunk source, the record sink), and the emulator core as the modems: the emulated network
(emulator/src/mipemu.c, through build/cosim/libmipcosim.so) of the central's MDP-810 and the
outstation's TRM-810, in virtual time, whose telegrams a test script may lose, duplicate or drop
(the core's fate hook). There is no modem model here: the emulator core is the modem.

The program is generated so that every register block also exists as plain WORD variables
(`snd_w0..snd_w122` for the write block, `snd_r0..snd_r124` for the read block, ...): matiec's
VARIABLES.csv does not list arrays, so this keeps the tests runnable with either compiler.
"""
from __future__ import annotations

import ctypes
import functools
import os
import random
import struct
import weakref
from dataclasses import dataclass
from pathlib import Path

from mipcosim.programs import enum_values  # noqa: F401 (the tests import it from here)
from mipcosim.kernel import FATE_FN as _FATE_FN, MS, CosimError, Kernel, Stats as _Stats, kernel_lib
from mipcosim.kernel import Radio as KernelRadio
from plcharness import Plc, PlcError
from mipprobe.regmap import MDP810, TRM810

# the numbers of st_lib's enumerations, read from st_lib/core/MIP_Types.st (never copied by hand)
ERR = enum_values("E_MIP_Error")
SND = enum_values("E_MIP_SenderState")
WAIT = enum_values("E_MIP_WaitReason")
RCV = enum_values("E_MIP_ReceiverState")

REPO = Path(__file__).resolve().parents[2]
LIB = REPO / "st_lib"
from mipcosim.programs import LIB_FILES   # import order, the one list
LIB_PATHS = [str(LIB / f) for f in LIB_FILES]

HAS_WRITE = {"MIP_Sender", "MIP_Receiver", "MIP_Link", "MIP_BufferSender"}
HAS_CHUNK = {"MIP_Sender", "MIP_Link"}
HAS_RECORD = {"MIP_Receiver", "MIP_Link"}
FFFF = 0xFFFF


def dialect() -> str:
    """"st", or "scl" under PLCRT_STLIB_DIALECT=scl (make scl-tests): the bench then builds the
    library from the TIA SCL that stc.scl_out generates from st_lib (docs/wiring-s7.md), so
    the behaviour tests run the generated SCL."""
    d = os.environ.get("PLCRT_STLIB_DIALECT") or "st"
    if d not in ("st", "scl"):
        raise ValueError(f"PLCRT_STLIB_DIALECT must be st or scl, not {d!r}")
    return d


def lib_type(name: str) -> str:
    """How a test program declares a variable of st_lib's type `name`: the name itself, or
    under the SCL dialect, where the library has no array type names, `ARRAY[..] OF ..`, and
    no enumerations, INT."""
    if dialect() != "scl":
        return name
    if name.startswith("E_MIP_"):
        return "INT"            # TIA has no enumerations: the SCL export's enums are Int
    return _array_aliases().get(name.upper(), name)


@functools.lru_cache(maxsize=None)
def _array_aliases():
    from stc.scl_out import array_aliases
    return array_aliases(LIB_PATHS)      # parses st_lib: once per process


def lib_sources(workdir: Path) -> list[str]:
    """The library files a bench builds its program with: st_lib/*/*.st, or under the SCL
    dialect the generated .scl (any bench that builds through this runs on the SCL too)."""
    if dialect() != "scl":
        return LIB_PATHS
    if compiler() != "stc":
        raise ValueError("PLCRT_STLIB_DIALECT=scl needs stc (matiec reads no SCL)")
    return scl_library(workdir)


def scl_library(workdir: Path) -> list[str]:
    """The generated .scl files of st_lib, written once per directory, in import order."""
    from stc.scl_out import generate_files, library_version
    out = Path(workdir) / "scl"
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for src, text in generate_files(LIB_PATHS, library_version(LIB_PATHS)).items():
        dst = out / (Path(src).stem + ".scl")
        dst.write_text(text)
        paths.append(str(dst))
    return paths


def compiler() -> str:
    """stc unless PLCRT_COMPILER / STLIB_COMPILER says otherwise (CI runs stc)."""
    return os.environ.get("STLIB_COMPILER") or os.environ.get("PLCRT_COMPILER") or "stc"


def gen_program(instances, tick_ms=10):
    """instances: list of (name, fb type). Returns the ST text of PROGRAM MAIN + configuration."""
    decl, pre, post, calls = [], [], [], []

    for name, fb in instances:
        decl.append(f"  {name} : {fb};")
        decl.append(f"  {name}_rd : {lib_type('MIP_T_ReadBlock')};")
        decl.append("  " + ", ".join(f"{name}_r{i}" for i in range(125)) + " : WORD;")
        pre += [f"{name}_rd[{i}] := {name}_r{i};" for i in range(125)]
        args = [f"aRead := {name}_rd"]
        if fb in HAS_WRITE:
            decl.append("  " + ", ".join(f"{name}_w{i}" for i in range(123)) + " : WORD;")
            post += [f"{name}_w{i} := {name}.aWrite[{i}];" for i in range(123)]
        if fb in HAS_CHUNK:
            decl.append(f"  {name}_ck : {lib_type('MIP_T_Payload')};")
            decl.append("  " + ", ".join(f"{name}_c{i}" for i in range(122)) + " : WORD;")
            pre += [f"{name}_ck[{i}] := {name}_c{i};" for i in range(122)]
            args.append(f"aChunk := {name}_ck")
        if fb in HAS_RECORD:
            decl.append("  " + ", ".join(f"{name}_p{i}" for i in range(122)) + " : WORD;")
            post += [f"{name}_p{i} := {name}.aRecord[{i}];" for i in range(122)]
        if fb == "MIP_BufferSender":
            decl.append(f"  {name}_buf : {lib_type('MIP_T_Buffer')};")
            decl.append(f"  {name}_fill : BOOL;")
            decl.append(f"  {name}_seed : UINT;")
            decl.append(f"  {name}_i : UINT;")
            pre.append(f"IF {name}_fill THEN\n  FOR {name}_i := 0 TO 8191 DO\n"
                       f"    {name}_buf[{name}_i] := UINT_TO_WORD({name}_i * 7 + {name}_seed);\n"
                       f"  END_FOR;\nEND_IF;")
            args.append(f"aBuffer := {name}_buf")
        calls.append(f"{name}({', '.join(args)});")
    return ("(* generated by tests/st_lib/stlib_sim.py *)\nPROGRAM MAIN\nVAR\n" + "\n".join(decl)
            + "\nEND_VAR\n" + "\n".join(pre) + "\n" + "\n".join(calls) + "\n" + "\n".join(post)
            + f"\nEND_PROGRAM\n\nCONFIGURATION Config0\n  RESOURCE Res0 ON PLC\n"
            f"    TASK tMain(INTERVAL := T#{tick_ms}ms, PRIORITY := 0);\n"
            f"    PROGRAM inst0 WITH tMain : MAIN;\n  END_RESOURCE\nEND_CONFIGURATION\n")


_BUILDS = {}


def build(instances, workdir: Path, tick_ms=10) -> Plc:
    """Build (once per program text and compiler, then a fresh instance per call)."""
    return build_text(gen_program(instances, tick_ms), workdir)


def build_text(text, workdir: Path, subdir="build") -> Plc:
    """The library and one program (its text): built once per text, compiler and dialect,
    then a fresh instance per call (also for tests/st_lib/soe_bench.py)."""
    key = (text, compiler(), dialect())
    if key not in _BUILDS:
        bdir = Path(workdir) / subdir
        bdir.mkdir(parents=True, exist_ok=True)
        prog = bdir / "prog_main.st"
        prog.write_text(text)
        plc = Plc.build(lib_sources(bdir) + [str(prog)], workdir=bdir, compiler=compiler())
        _BUILDS[key] = (plc.build_result, bdir)
        return plc
    result, bdir = _BUILDS[key]
    return Plc(result, bdir)


class Fb:
    """One FB instance of the test program, seen through its scalar shims."""

    def __init__(self, plc: Plc, name: str):
        self.plc, self.n = plc, name

    def __getitem__(self, member):
        return self.plc[f"MAIN.{self.n}.{member}"]

    def __setitem__(self, member, value):
        self.plc[f"MAIN.{self.n}.{member}"] = value

    def has(self, member):
        try:
            self[member]
            return True
        except PlcError:
            return False

    def write_block(self, length=None):
        if length is None:
            length = self["uWriteLen"]
        return [self.plc[f"MAIN.{self.n}_w{i}"] for i in range(length)]

    def set_read(self, block):
        for i in range(125):
            self.plc[f"MAIN.{self.n}_r{i}"] = block[i] if i < len(block) else 0

    def set_chunk(self, data):
        for i in range(122):
            self.plc[f"MAIN.{self.n}_c{i}"] = data[i] if i < len(data) else 0

    def record(self, length):
        return [self.plc[f"MAIN.{self.n}_p{i}"] for i in range(length)]


# ---------------------------------------------------------------- the emulator core as the modems

FATES = {"ok": 0, "lost": 1, "dup": 2, "drop": 3}       # MIPEMU_FATE_*
_lib = kernel_lib          # libmipcosim.so: the emulator core's API, the one binding


class ModbusException(AssertionError):
    """The emulator answered a request with a Modbus exception (an integration error here)."""


class Endpoint:
    """One modem of the emulated network as its Modbus client sees it: the outstation's TRM-810
    (endpoint = its station) or the central's MDP-810 (endpoint 0, unit id = the station). `write` and
    `read125` are Modbus TCP frames through mipemu_handle, as the PLC's master sends them;
    `receive`, `read_area`, `write_area` and the status bits are the tests' white-box access
    (mipemu_net_inject / mipemu_net_peek, no side effects on "new data")."""

    # write area, read status, read data: emulator/README.md, register maps
    MDP, TRM = ((m.write_data, m.read_status, m.read_data) for m in (MDP810, TRM810))

    def __init__(self, radio: "Radio", ep: int, unit: int):
        self.radio, self.ep, self.unit = radio, ep, unit
        self.static_n = radio.static_n
        self.wbase, self.rstat, self.rbase = self.MDP if ep == 0 else self.TRM
        self.writes = 0                   # blocks written through write()
        self._tid = 0
        self._out = ctypes.create_string_buffer(300)     # MIPEMU_RESPONSE_MAX

    def _request(self, pdu: bytes) -> bytes:
        self._tid = (self._tid + 1) & 0xFFFF
        req = struct.pack(">HHHB", self._tid, 0, len(pdu) + 1, self.unit) + pdu
        n = _lib().mipemu_handle(self.radio.net, self.ep, req, len(req), self._out, len(self._out))
        if n < 9:
            raise ModbusException(f"endpoint {self.ep}: connection closed on {pdu[:1].hex()}")
        resp = self._out.raw[:n]
        assert struct.unpack(">H", resp[:2])[0] == self._tid
        if resp[7] & 0x80:
            raise ModbusException(f"endpoint {self.ep}: exception {resp[8]:02X} on FC{pdu[0]}")
        return resp[7:]

    def write(self, block):
        """One FC16 write of the block to the write area."""
        n = len(block)
        self._request(struct.pack(f">BHHB{n}H", 16, self.wbase, n, 2 * n, *block))
        self.writes += 1

    def read125(self):
        """One FC3 read of 125 registers at the read-status register: [status, count, data...];
        clears 'new data' (after the answer was composed)."""
        r = self._request(struct.pack(">BHH", 3, self.rstat, 125))
        return list(struct.unpack(">125H", r[2:]))

    def receive(self, block):
        """A block arrives in the read area as if the radio had delivered it."""
        arr = (ctypes.c_uint16 * len(block))(*block)
        if _lib().mipemu_net_inject(self.radio.net, self.ep, self.unit, arr, len(block)) != 0:
            raise ValueError(f"cannot inject a block of {len(block)} registers")

    def peek(self, addr, n):
        out = (ctypes.c_uint16 * n)()
        if _lib().mipemu_net_peek(self.radio.net, self.ep, self.unit, addr, n, out) != 0:
            raise IndexError(f"registers {addr}..{addr + n - 1} of endpoint {self.ep}")
        return list(out)

    def status(self):
        return self.peek(self.rstat, 1)[0]

    @property
    def new_data(self):
        return bool(self.status() & 1)

    @property
    def waiting(self):
        return bool(self.status() & 2)

    @property
    def unconfirmed(self):
        return bool(self.status() & 16)

    @property
    def read_area(self):
        return _Area(self, self.rbase, writable=True)

    @property
    def write_area(self):
        return _Area(self, self.wbase, writable=False)


class _Area:
    """The 148 registers of a read or write area, peeked. Setting a read-area register (white
    box) changes that register only: the count stays, and so does bit 0 ('new data')."""

    def __init__(self, ep: Endpoint, base, writable):
        self.ep, self.base, self.writable = ep, base, writable

    def __len__(self):
        return 148

    def __getitem__(self, i):
        return self.ep.peek(self.base, 148)[i]

    def __setitem__(self, i, value):
        if not self.writable:
            raise TypeError("the write area is written by Modbus (Endpoint.write)")
        status, count = self.ep.peek(self.ep.rstat, 2)
        area = self.ep.peek(self.base, 148)
        area[i] = value
        self.ep.receive(area[:max(count, i + 1)])
        if not status & 1:
            self.ep.read125()             # the bit was clear: a read clears it again


@dataclass
class Telegram:
    src: str            # "O" outstation -> central (the answer), "C" central -> outstation (the poll)
    block: list
    fate: str           # "ok", "lost", "dup", "drop": what `fate` said (emulator/README.md)
    poll: int = 0       # the radio poll (slot) it went in: a poll is the central's telegram,
                        # then the outstation's


class Radio:
    """The emulated network (emulator/src/mipemu.c through libmipcosim.so): the outstation is
    its last station, with the TRM-810 `outstation`; the central's MDP-810 is `central`. It
    runs in virtual time (`advance`, one scan tick per bench step). Every telegram that carries
    a block is logged, and `fate(src, block)` decides it: "ok", "lost" (the link repeats it; a
    lost poll gets no answer, a lost answer loses the confirmation of the poll's block too),
    "dup" (delivered, its confirmation lost), "drop" (confirmed, never delivered).

    Timing: the outstation is polled every `poll_scans` scans (1 ms more if it sent a block),
    first at the end of the first cycle, and its poll, answer and ack follow each other within
    about 3 ms. A fast radio (10 Mbit/s, 1 byte of overhead: air time under 0.2 ms) with slot
    gaps of 1 ms, and idle stations 1.. before it, whose empty slots (2 ms each) fill the rest
    of the polling cycle."""

    BITRATE = 10_000_000
    OVERHEAD = 1
    GAP_NS = 1 * MS

    def __init__(self, static_n=0, fate=None, poll_scans=5, tick_ms=10, seed=1):
        self.static_n, self.poll_scans = static_n, poll_scans
        self.stations = max(1, poll_scans * tick_ms * MS // (2 * self.GAP_NS))
        try:
            kernel = Kernel(self.stations, static=bool(static_n), static_registers=static_n or 148,
                            seed=seed, radio=KernelRadio(self.BITRATE, self.GAP_NS, self.OVERHEAD))
        except CosimError as e:
            raise RuntimeError(f"emulator: {e}") from None
        self._kernel = kernel
        weakref.finalize(self, kernel.close)
        self._sim = kernel.handle
        self.net = kernel.net
        self.fate = fate or (lambda src, block: "ok")
        self.log: list[Telegram] = []
        self.now = 0
        self._error = None
        self._hook = _FATE_FN(self._on_telegram)   # referenced as long as the network lives
        kernel.lib.mipemu_net_set_fate(self.net, self._hook, None)
        self.station = self.stations
        self.outstation = Endpoint(self, self.station, 1)
        self.central = Endpoint(self, 0, self.station)

    def _on_telegram(self, _user, _station, up, blk, n):
        try:
            src, block = ("O" if up else "C"), blk[:n]
            fate = self.fate(src, block)
            st = _Stats()
            _lib().mipemu_net_stats(self.net, self.station, ctypes.byref(st))
            self.log.append(Telegram(src, block, fate, st.polls))
            return FATES[fate]
        except BaseException as e:        # raised again in advance()
            self._error = self._error or e
            return 0

    def advance(self, ns):
        """Runs the radio `ns` further in virtual time."""
        self.now += ns
        _lib().mipemu_net_advance(self.net, self.now)
        if self._error:
            e, self._error = self._error, None
            raise e

    def stats(self):
        st = _Stats()
        _lib().mipemu_net_stats(self.net, self.station, ctypes.byref(st))
        return {n: getattr(st, n) for n, _ in _Stats._fields_}

    def counters(self, idx=0):
        return [(t.src, t.block[idx] if len(t.block) > idx else None, t.fate) for t in self.log]


class Port:
    """The runtime's side of one FB: its Modbus client, trigger-policy FC16 writes of the block
    into the modem's write area, FC3 reads of 125 registers at the read status (Endpoint).

    read_mode: "trigger" (valid for one scan per read, every read_every scans) or "cyclic"
    (OpenPLC: valid always, data refreshed every read_every scans)."""

    def __init__(self, fb: Fb, modem: Endpoint, read_every=2, read_mode="trigger"):
        self.fb, self.modem = fb, modem
        self.read_every, self.read_mode = read_every, read_mode
        self.write_fail = 0               # fail the next n writes
        self.read_fail = 0                # <> 0: every read fails with this status (a dead link)
        self.fail_rate = 0.0              # and each write with this probability
        self.rng = random.Random(0)
        self.writes: list[list] = []
        self._done = self._err = False
        self._k = 0

    def before_scan(self):
        self._k += 1
        fb = self.fb
        if self.read_fail:
            # the runtime's read handshake ends in error (plcrt: error bit and status word)
            fail = self._k % self.read_every == 0 or self.read_mode == "cyclic"
            fb["xReadValid"] = False
            fb["xReadError"] = fail
            fb["wReadStatus"] = self.read_fail if fail else 0
            return
        fb["xReadError"] = False
        if self.read_mode == "cyclic":
            if self._k % self.read_every == 0 or self._k == 1:
                fb.set_read(self.modem.read125())
            fb["xReadValid"] = True
        else:
            if self._k % self.read_every == 0:
                fb.set_read(self.modem.read125())
                fb["xReadValid"] = True
            else:
                fb["xReadValid"] = False

    def after_scan(self):
        fb = self.fb
        req = fb["xWriteReq"]
        if req and not (self._done or self._err):
            if self.write_fail > 0 or (self.fail_rate and self.rng.random() < self.fail_rate):
                self.write_fail = max(0, self.write_fail - 1)
                self._err = True
            else:
                block = fb.write_block()
                self.writes.append(block)
                self.modem.write(block)
                self._done = True
        elif not req:
            self._done = self._err = False
        fb["xWriteDone"] = self._done
        fb["xWriteError"] = self._err


class ChunkSource:
    """The caller of MIP_Sender's chunk handshake, serving `data` in chunks of uChunkMax."""

    def __init__(self, fb: Fb, data):
        self.fb, self.data = fb, list(data)
        self.served = []
        self.hold_from = None             # do not serve chunk indexes >= this (caller busy)

    def before_scan(self):
        fb = self.fb
        if fb["xChunkRequest"] and (self.hold_from is None or fb["udiChunkIndex"] < self.hold_from):
            idx, cmax = fb["udiChunkIndex"], fb["uChunkMax"]
            part = self.data[idx * cmax:(idx + 1) * cmax]
            last = (idx + 1) * cmax >= len(self.data)
            fb.set_chunk(part)
            fb["uChunkLen"] = len(part)
            fb["xChunkLast"] = last
            fb["xChunkValid"] = True
            self.served.append(idx)
        else:
            fb["xChunkValid"] = False


class RecordSink:
    """Collects what MIP_Receiver delivers; assembles transfers. pulse=True: every scan with
    xRecordValid is a delivery (so a record shown twice counts twice); pulse=False (caller
    acknowledges): a delivery is a rising edge of xRecordValid."""

    def __init__(self, fb: Fb, pulse=True):
        self.fb = fb
        self.pulse = pulse
        self._prev = False
        self.records = []        # (number, payload)
        self.transfers = []      # complete transfers (payload lists)
        self.current = []
        self.failed = 0
        self._end = "xRecvTransferEnd" if fb.has("xRecvTransferEnd") else "xTransferEnd"

    def after_scan(self):
        fb = self.fb
        valid = fb["xRecordValid"]
        fresh = valid and (self.pulse or not self._prev)
        self._prev = valid
        if fresh:
            num, n = fb["wRecordNumber"], fb["uRecordLen"]
            payload = fb.record(n)
            if num == 1:
                self.current = []
            assert fb["udiRecordOffset"] == len(self.current), "offset does not match delivered data"
            self.records.append((num, payload))
            self.current += payload
        # the end of a transfer: MIP_Receiver's xTransferEnd (MIP_Link: xRecvTransferEnd), one
        # scan; its 16#FFFF was delivered above if it had data (an empty one is not)
        if fb[self._end]:
            self.transfers.append(self.current)
            self.current = []


class RunUntil:
    """run_until for a bench with step(): scans until cond() holds, at most `limit` scans;
    says whether it held (the benches here and in soe_bench / unicos_bench share it)."""

    def run_until(self, cond, limit):
        for _ in range(limit):
            if cond():
                return True
            self.step()
        return cond()


class Bench(RunUntil):
    """Steps one or more PLCs (an outstation PLC, a central PLC) in lockstep with their ports
    and the radio: after each scan the radio runs one scan tick further in virtual time
    (`radio = None`: the radio stands still, the modems still answer their clients)."""

    def __init__(self, plcs, parts, radio=None, check_plcopen=(), tick_ms=10):
        self.plcs = list(plcs)
        self.parts = list(parts)
        self.radio = radio
        self.tick_ns = tick_ms * MS
        self.scans = 0
        self.check_plcopen = list(check_plcopen)   # (fb, member names of which one at most is TRUE)

    def step(self, n=1):
        for _ in range(n):
            for p in self.parts:
                if hasattr(p, "before_scan"):
                    p.before_scan()
            for plc in self.plcs:
                plc.scan()
            self.scans += 1
            for p in self.parts:
                if hasattr(p, "after_scan"):
                    p.after_scan()
            for fb, names in self.check_plcopen:
                flags = [fb[m] for m in names]
                assert sum(flags) <= 1, f"{fb.n}: more than one of {names} TRUE: {flags}"
            if self.radio:
                self.radio.advance(self.tick_ns)

    def restart(self, old_plc, fbs, instances, workdir):
        """A PLC restart: a fresh instance of the same program (all state lost) replaces
        old_plc; the modems (the emulated network) keep their registers."""
        new = build(instances, workdir)
        self.plcs[self.plcs.index(old_plc)] = new
        for fb in fbs:
            fb.plc = new
        return new


def pattern(n, seed=0):
    rnd = random.Random(seed)
    return [rnd.randrange(65536) for _ in range(n)]


# ---------------------------------------------------------------- ready-made set-ups

ALL = [("snd", "MIP_Sender"), ("rcv", "MIP_Receiver"), ("lo", "MIP_Link"), ("lc", "MIP_Link"),
       ("bs", "MIP_BufferSender"), ("st", "MIP_Status")]
PLCOPEN_SND = ("xDone", "xBusy", "xError")
PLCOPEN_LINK_S = ("xSendDone", "xSendBusy", "xSendError")
PLCOPEN_RCV = (("xValid", "xError"), ("xBusy", "xError"))   # enable-type: xError excludes both
PLCOPEN_LINK_R = (("xRecvValid", "xRecvError"), ("xRecvBusy", "xRecvError"))


class Uni:
    """Unidirectional: an outstation PLC with MIP_Sender `snd` (or MIP_BufferSender `bs`), a
    central PLC with MIP_Receiver `rcv`, the emulated network in dynamic (or static) mode:
    `mo` the outstation's TRM-810, `mc` the central's MDP-810."""

    def __init__(self, workdir, data=(), polled=False, static_n=0, timeout_ms=300,
                 read_every=2, read_mode="trigger", fate=None, chunk=123, buffer=False,
                 poll_scans=5, transfer_timeout_ms=0, enable=True):
        self.workdir = workdir
        self.plc_o = build(ALL, workdir)
        self.plc_c = build(ALL, workdir)
        self.snd = Fb(self.plc_o, "bs" if buffer else "snd")
        self.rcv = Fb(self.plc_c, "rcv")
        self.radio = Radio(static_n, fate, poll_scans)
        self.mo, self.mc = self.radio.outstation, self.radio.central
        self.port_o = Port(self.snd, self.mo, read_every, read_mode)
        self.port_c = Port(self.rcv, self.mc, read_every, read_mode)
        self.sink = RecordSink(self.rcv)
        parts = [self.port_o, self.port_c, self.sink]
        self.src = None
        if not buffer:
            self.src = ChunkSource(self.snd, data)
            parts.insert(0, self.src)
        self.bench = Bench([self.plc_o, self.plc_c], parts, self.radio,
                           [(self.snd, PLCOPEN_SND)] + [(self.rcv, r) for r in PLCOPEN_RCV])
        self.settings = dict(polled=polled, static=bool(static_n), timeout_ms=timeout_ms,
                             chunk=chunk, transfer_timeout_ms=transfer_timeout_ms,
                             enable=enable)
        self.configure_sender()
        self.configure_receiver()

    def configure_sender(self):
        s, st = self.snd, self.settings
        s["xPolled"], s["xStatic"] = st["polled"], st["static"]
        s["tTimeout"] = st["timeout_ms"] * MS
        s["uChunkSize"] = st["chunk"]

    def configure_receiver(self):
        r, st = self.rcv, self.settings
        r["xPolled"], r["xStatic"] = st["polled"], st["static"]
        r["tTimeout"] = st["timeout_ms"] * MS
        r["tTransferTimeout"] = st["transfer_timeout_ms"] * MS
        r["xEnable"] = st["enable"]

    def send(self, limit=5000):
        """Run one transfer: rising edge of xExecute, until done or error. Returns 'done'/'error'."""
        s = self.snd
        s["xExecute"] = False
        self.bench.step()
        s["xExecute"] = True
        ok = self.bench.run_until(lambda: s["xDone"] or s["xError"], limit)
        assert ok, f"transfer neither done nor failed after {limit} scans (state {s['eState']})"
        result = "done" if s["xDone"] else "error"
        s["xExecute"] = False
        self.bench.step(2)
        return result

    def restart_outstation(self):
        self.plc_o = self.bench.restart(self.plc_o, [self.snd], ALL, self.workdir)
        self.configure_sender()

    def restart_central(self):
        self.plc_c = self.bench.restart(self.plc_c, [self.rcv], ALL, self.workdir)
        self.sink.current = []
        self.configure_receiver()


class Bi:
    """Bidirectional (note 2.2): MIP_Link `lo` on the outstation PLC, `lc` on the central PLC."""

    def __init__(self, workdir, data_o=(), data_c=(), polled=False, static_n=0, timeout_ms=300,
                 read_every=2, read_mode="trigger", fate=None, chunk=123, poll_scans=5):
        self.workdir = workdir
        self.plc_o = build(ALL, workdir)
        self.plc_c = build(ALL, workdir)
        self.lo, self.lc = Fb(self.plc_o, "lo"), Fb(self.plc_c, "lc")
        self.radio = Radio(static_n, fate, poll_scans)
        self.mo, self.mc = self.radio.outstation, self.radio.central
        self.src_o, self.src_c = ChunkSource(self.lo, data_o), ChunkSource(self.lc, data_c)
        self.sink_o, self.sink_c = RecordSink(self.lo), RecordSink(self.lc)
        self.port_o = Port(self.lo, self.mo, read_every, read_mode)
        self.port_c = Port(self.lc, self.mc, read_every, read_mode)
        self.bench = Bench([self.plc_o, self.plc_c],
                           [self.src_o, self.src_c, self.port_o, self.port_c,
                            self.sink_o, self.sink_c], self.radio,
                           [(fb, names) for fb in (self.lo, self.lc)
                            for names in (PLCOPEN_LINK_S,) + PLCOPEN_LINK_R])
        for fb, central in ((self.lo, False), (self.lc, True)):
            fb["xCentral"] = central
            fb["xPolled"], fb["xStatic"] = polled, bool(static_n)
            fb["tTimeout"] = timeout_ms * MS
            fb["uChunkSize"] = chunk
            fb["xEnable"] = True

    def send_both(self, limit=8000):
        for fb in (self.lo, self.lc):
            fb["xExecute"] = True
        ok = self.bench.run_until(lambda: all(fb["xSendDone"] or fb["xSendError"]
                                              for fb in (self.lo, self.lc)), limit)
        assert ok, "transfers neither done nor failed"
        res = ["done" if fb["xSendDone"] else "error" for fb in (self.lo, self.lc)]
        for fb in (self.lo, self.lc):
            fb["xExecute"] = False
        self.bench.step(2)
        return res


class CyclicPort(Port):
    """OpenPLC's cyclic master: every `read_every` scans it writes the whole write image
    (whatever the block shows, request or not) and reads the read block; there is no done
    signal, so the program counts a write request as done after `done_scans` scans (as
    plc/ does with a TON)."""

    def __init__(self, fb, modem, read_every=3, done_scans=4):
        super().__init__(fb, modem, read_every, "cyclic")
        self.done_scans = done_scans
        self._held = 0

    def after_scan(self):
        fb = self.fb
        if self._k % self.read_every == 0:
            n = self.modem.static_n or 123
            block = fb.write_block(n)
            self.writes.append(block)
            self.modem.write(block)
        req = fb["xWriteReq"]
        self._held = self._held + 1 if req else 0
        fb["xWriteDone"] = req and self._held >= self.done_scans
        fb["xWriteError"] = False
