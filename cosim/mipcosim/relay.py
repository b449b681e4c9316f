"""The emulator's SIPROTEC relay (emulator/src/siprotec.c, docs/chain.md "The relay") in the
co-simulation's virtual time (issue 35): `Relay` adds one to a kernel (mipcosim_relay_add), so
that mipcosim_run lets its event source run with the PLCs' time, and connects a PLC's Modbus
device to it in process (mipcosim_connect_relay), or answers Modbus TCP frames of a caller
that is not a plcrt PLC (`handle`, e.g. tests/st_lib/soe_bench.py).

    k = RelayKernel()
    relay = Relay(kernel=k, origin_ms=1767225600000, rate=2.0)
    pid = k.add_plc(plc)                    # a plcharness Plc
    relay.connect(pid, plc, "relay")        # the PLC's device "relay" reads the relay
    k.run(10 * 10**9)                       # 10 s of virtual time
"""
from __future__ import annotations

import ctypes

from .kernel import CosimError, Kernel

OVERFLOW = {"drop-oldest": 0, "drop-new": 1}     # SIPROTEC_OVF_*
BAD_ACK = {"exc03": 0, "ignore": 1}              # SIPROTEC_BAD_ACK_*
RESPONSE_MAX = 260                               # SIPROTEC_RESPONSE_MAX


class RelayConfig(ctypes.Structure):
    """siprotec_config (emulator/include/siprotec.h)."""
    _fields_ = [("base", ctypes.c_uint16), ("capacity", ctypes.c_uint32),
                ("overflow", ctypes.c_int), ("seq_bits", ctypes.c_int),
                ("bad_ack", ctypes.c_int), ("rate", ctypes.c_double),
                ("burst_n", ctypes.c_uint32), ("burst_every_s", ctypes.c_double),
                ("time_origin_ms", ctypes.c_uint64)]


class RelayStats(ctypes.Structure):
    """siprotec_stats."""
    _fields_ = [("entries", ctypes.c_uint32), ("generated", ctypes.c_uint64),
                ("dropped", ctypes.c_uint64), ("acknowledged", ctypes.c_uint64),
                ("reset_cleared", ctypes.c_uint64), ("bad_acks", ctypes.c_uint64),
                ("seq", ctypes.c_uint16), ("offered", ctypes.c_uint16)]


class RelayKernel(Kernel):
    """A kernel with one idle radio station, for relays and the PLCs that read them (no
    radio traffic): `add_plc` a plcharness Plc, `Relay(kernel=k)`, `relay.connect(pid, plc,
    device)`, then `run(until_ns)` scans the PLCs and lets the relays' events happen in virtual
    time. A Relay made without a kernel gets one of its own."""

    def __init__(self):
        super().__init__(1, static_registers=148)

    def run(self, until_ns):
        self.run_until(until_ns)

    def __del__(self):
        if getattr(self, "_handle", None) is not None:
            self.close()


class Relay:
    """One relay. Parameters as `mip-emulator --relay` (docs/chain.md's table): base (PDU
    address of 40601), capacity, overflow ("drop-oldest" | "drop-new"), seq_bits (2..8),
    bad_ack ("exc03" | "ignore"), rate (events/s), burst (N, every S seconds), origin_ms (the
    time stamp of virtual time 0). `events`: scripted (t_s, [type/bit, address, cause/type,
    value]). `kernel`: the Kernel it joins (a LoggerLink's or Network's .kernel); None: a kernel of
    its own, moved on by advance()."""

    def __init__(self, events=(), *, kernel=None, base=600, capacity=200,
                 overflow="drop-oldest", seq_bits=8, bad_ack="exc03", rate=0.0, burst=None,
                 origin_ms=0):
        if overflow not in OVERFLOW:
            raise CosimError(f"overflow {overflow!r}: use drop-oldest or drop-new")
        if bad_ack not in BAD_ACK:
            raise CosimError(f"bad_ack {bad_ack!r}: use exc03 or ignore")
        self.kernel = kernel or RelayKernel()
        self.lib = self.kernel.lib
        cfg = RelayConfig()
        self.lib.siprotec_config_default(ctypes.byref(cfg))
        cfg.base, cfg.capacity, cfg.seq_bits = base, capacity, seq_bits
        cfg.overflow, cfg.bad_ack, cfg.rate = OVERFLOW[overflow], BAD_ACK[bad_ack], rate
        if burst:
            cfg.burst_n, cfg.burst_every_s = burst
        cfg.time_origin_ms = origin_ms
        self.origin_ms = origin_ms
        self._cfg = cfg                   # for restart()
        self.rid = self.lib.mipcosim_relay_add(self.kernel.handle, ctypes.byref(cfg))
        if self.rid < 0:
            raise CosimError(self.lib.mipcosim_errmsg(self.kernel.handle).decode())
        self.core = self.lib.mipcosim_relay(self.kernel.handle, self.rid)
        self._rsp = ctypes.create_string_buffer(RESPONSE_MAX)
        for t_s, words in events:
            self.add(t_s, words)

    def add(self, t_s, words):
        """A scripted event at t_s seconds of virtual time (not before now)."""
        w = (ctypes.c_uint16 * 4)(*words)
        if self.lib.siprotec_script(self.core, int(round(t_s * 1e9)), w) != 0:
            raise CosimError("relay: out of memory")

    def restart(self, events=()):
        """A power cycle at the current virtual time (mipcosim_relay_restart): the recorder empty,
        the sequence number 0, the same configuration; `events` scripted anew (t_s not before
        now). Connected PLCs talk to the restarted relay; stats() start from 0."""
        if self.lib.mipcosim_relay_restart(self.kernel.handle, self.rid, ctypes.byref(self._cfg)) != 0:
            raise CosimError(self.lib.mipcosim_errmsg(self.kernel.handle).decode())
        self.core = self.lib.mipcosim_relay(self.kernel.handle, self.rid)
        for t_s, words in events:
            self.add(t_s, words)

    def advance(self, now_ns):
        """Virtual time to now_ns (RelayKernel.run: PLCs added to it are scanned too)."""
        if not isinstance(self.kernel, RelayKernel):
            raise CosimError("advance: the relay's kernel runs the time (mipcosim_run)")
        self.kernel.run(now_ns)

    def handle(self, adu: bytes):
        """One Modbus TCP request frame -> the response frame (None: the relay would close the
        connection)."""
        n = self.lib.mipcosim_relay_request(self.kernel.handle, self.rid, adu, len(adu),
                                            self._rsp, len(self._rsp))
        return None if n < 0 else self._rsp.raw[:n]

    def connect(self, pid, plc, device):
        """PLC pid of the kernel (its plcharness Plc `plc`): its Modbus device `device` talks
        to this relay in process."""
        setter = ctypes.cast(plc.library.plcrt_device_set_transport, ctypes.c_void_p)
        if self.lib.mipcosim_connect_relay(self.kernel.handle, pid, setter, device.encode(),
                                           self.rid) != 0:
            raise CosimError(self.lib.mipcosim_errmsg(self.kernel.handle).decode())

    def stats(self):
        st = RelayStats()
        self.lib.siprotec_get_stats(self.core, ctypes.byref(st))
        return {n: getattr(st, n) for n, _ in RelayStats._fields_}

    def entries(self):
        """Entries in the recorder, not yet acknowledged."""
        return self.stats()["entries"]

    def peek(self, addr, n):
        out = (ctypes.c_uint16 * n)()
        self.lib.siprotec_peek(self.core, addr, n, out)
        return list(out)
