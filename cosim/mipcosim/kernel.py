"""The co-simulation kernel (libmipcosim.so, cosim/include/mipcosim.h) as one object: `Kernel`
creates it, adds PLCs (plcharness Plc) and other participants (a Python scan function),
replaces or switches them off, connects their Modbus devices to the emulated modems, runs
virtual time and closes. Every caller (the chains here, the kit, the view, the bench, interop,
the docs' tools, the st_lib test bench) uses it; `kernel_lib` is the one ctypes binding.

    with Kernel(stations=2, loss_down=0.1, seed=7, radio=Radio.realistic()) as k:
        pid = k.add_plc(plc)                       # scanned every plc.tick_ns
        k.connect(pid, plc, "trm", 1)              # its device "trm" -> station 1's TRM-810
        k.run_until(10 * SEC)
"""
from __future__ import annotations

import ctypes
import json
from dataclasses import dataclass
from pathlib import Path

LIBDIR = Path(__file__).resolve().parents[2] / "build" / "cosim"
if (Path(__file__).resolve().parent / "_lib" / "libmipcosim.so").is_file():
    LIBDIR = Path(__file__).resolve().parent / "_lib"     # installed by the test kit (kit/)

# virtual time is counted in ns (mipcosim_now); the one definition of its units
MS = 1_000_000
SEC = 1_000_000_000


class CosimError(RuntimeError):
    pass


# the emulator core's trace hook (mipemu.h: mipemu_net_set_trace): one JSON line, its length
TRACE_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t)
# a participant's scan function (mipcosim.h: mipcosim_scan_fn(rt, n)): 0, or -1 to stop the run
SCAN_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_uint64)
# the emulator core's scripted-fault hook (mipemu.h: mipemu_fate_fn)
FATE_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                           ctypes.POINTER(ctypes.c_uint16), ctypes.c_int)


class Stats(ctypes.Structure):
    """mipemu_stats: one station's radio counters."""
    _fields_ = [(n, ctypes.c_uint64) for n in (
        "polls", "tel_down", "lost_down", "tel_up", "lost_up", "blocks_down", "blocks_up",
        "dup_down", "dup_up", "confirmed_down", "confirmed_up")]


_LIB = None


def kernel_lib():
    """libmipcosim.so with the argument types of the kernel's API (mipcosim.h) and of the
    emulator core's that it exports (mipemu.h); loaded once. The one binding: the chains here,
    the docs' tools, the bench and the st_lib test bench use it."""
    global _LIB
    if _LIB is not None:
        return _LIB
    path = LIBDIR / "libmipcosim.so"
    if not path.is_file():
        raise CosimError(f"{path} missing: run `make build/cosim/libmipcosim.so`")
    lib = ctypes.CDLL(str(path))
    c = ctypes
    u16p = c.POINTER(c.c_uint16)
    for name, res, args in [
        ("mipcosim_new_args", c.c_void_p, [c.c_int, c.c_int, c.c_int, c.c_double, c.c_double,
                                           c.c_double, c.c_uint64, c.c_uint32, c.c_uint64,
                                           c.c_int, c.c_char_p, c.c_size_t]),
        ("mipcosim_free", None, [c.c_void_p]),
        ("mipcosim_errmsg", c.c_char_p, [c.c_void_p]),
        ("mipcosim_net", c.c_void_p, [c.c_void_p]),
        ("mipcosim_now", c.c_uint64, [c.c_void_p]),
        ("mipcosim_plc_add", c.c_int, [c.c_void_p, c.c_void_p, c.c_void_p, c.c_uint64]),
        ("mipcosim_plc_replace", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_void_p, c.c_uint64]),
        ("mipcosim_connect", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_connect_tcp", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_connect_inproc", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_request", c.c_long, [c.c_void_p, c.c_int, c.c_char_p, c.c_size_t, c.c_void_p,
                                        c.c_size_t]),
        ("mipcosim_tap", c.c_int, [c.c_void_p, c.c_int, c.c_int, c.c_void_p, c.c_void_p, c.c_int,
                                   c.c_int, c.c_void_p, c.c_int]),
        ("mipcosim_tap_fields", c.c_int, [c.c_void_p, c.c_int, c.c_int, c.c_void_p, c.c_void_p,
                                          c.c_int, c.c_int, c.c_void_p, c.c_int]),
        ("mipcosim_untap", None, [c.c_void_p, c.c_int]),
        ("mipcosim_tap_read", c.c_size_t, [c.c_void_p, c.c_void_p, c.c_size_t]),
        ("mipcosim_run", c.c_int, [c.c_void_p, c.c_uint64]),
        ("mipcosim_failed_plc", c.c_int, [c.c_void_p]),
        ("mipcosim_requests", c.c_uint64, [c.c_void_p]),
        ("mipcosim_scans", c.c_uint64, [c.c_void_p]),
        ("mipcosim_trace_file", c.c_int, [c.c_void_p, c.c_char_p]),
        # the emulator core, for a caller that drives the network itself (tests/st_lib)
        ("mipemu_net_stats", c.c_int, [c.c_void_p, c.c_int, c.c_void_p]),
        ("mipemu_net_advance", c.c_int, [c.c_void_p, c.c_uint64]),
        ("mipemu_handle", c.c_long, [c.c_void_p, c.c_int, c.c_char_p, c.c_size_t,
                                     c.c_char_p, c.c_size_t]),
        ("mipemu_net_set_fate", None, [c.c_void_p, FATE_FN, c.c_void_p]),
        ("mipemu_net_inject", c.c_int, [c.c_void_p, c.c_int, c.c_int, u16p, c.c_int]),
        ("mipemu_net_peek", c.c_int, [c.c_void_p, c.c_int, c.c_int, c.c_uint, c.c_uint, u16p]),
        ("mipemu_net_set_trace", None, [c.c_void_p, TRACE_FN, c.c_void_p]),
        # SIPROTEC relays in the kernel's virtual time (issue 35; mipcosim.relay wraps them)
        ("mipcosim_relay_add", c.c_int, [c.c_void_p, c.c_void_p]),
        ("mipcosim_relay_restart", c.c_int, [c.c_void_p, c.c_int, c.c_void_p]),
        ("mipcosim_relay", c.c_void_p, [c.c_void_p, c.c_int]),
        ("mipcosim_connect_relay", c.c_int, [c.c_void_p, c.c_int, c.c_void_p, c.c_char_p, c.c_int]),
        ("mipcosim_relay_request", c.c_long, [c.c_void_p, c.c_int, c.c_char_p, c.c_size_t,
                                              c.c_char_p, c.c_size_t]),
        ("siprotec_config_default", None, [c.c_void_p]),
        ("siprotec_script", c.c_int, [c.c_void_p, c.c_uint64, u16p]),
        ("siprotec_next_event", c.c_uint64, [c.c_void_p]),
        ("siprotec_peek", None, [c.c_void_p, c.c_uint16, c.c_uint, u16p]),
        ("siprotec_get_stats", None, [c.c_void_p, c.c_void_p]),
    ]:
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    _LIB = lib
    return lib



def read_taps(lib, sim):
    """The entries the kernel's taps logged since the last call, oldest first: (tap slot, PLC
    id, words) (mipcosim_tap_read's [tap, plc, n, words...])."""
    buf = (ctypes.c_uint16 * 65536)()
    while True:
        n = lib.mipcosim_tap_read(sim, buf, len(buf))
        if n == 0:
            return
        i = 0
        while i < n:
            k = buf[i + 2]
            yield buf[i], buf[i + 1], list(buf[i + 3:i + 3 + k])
            i += 3 + k


def radio_stats(lib, sim, stations):
    """The emulator's radio counters summed over `stations`, and the kernel's scans and
    Modbus requests."""
    tot = {}
    for s in stations:
        st = Stats()
        lib.mipemu_net_stats(lib.mipcosim_net(sim), s, ctypes.byref(st))
        for name, _ in Stats._fields_:
            tot[name] = tot.get(name, 0) + getattr(st, name)
    tot["requests"] = lib.mipcosim_requests(sim)
    tot["scans"] = lib.mipcosim_scans(sim)
    return tot


@dataclass
class Radio:
    """Radio parameters of the emulator network."""
    bitrate: int = 1_000_000        # fast: a slot of a few ms
    slot_gap_ns: int = 1 * MS
    overhead_bytes: int = 12

    @classmethod
    def realistic(cls):
        return cls(9600, 20 * MS, 12)


TRANSPORTS = ("inproc", "socketpair", "tcp")      # Kernel.connect's ways to a modem


class Kernel:
    """One co-simulation kernel: an MDP-810 and `stations` TRM-810s of the emulator core, and
    the participants it scans in lockstep virtual time. Named arguments: static (the modems
    in static mode, static_registers each), loss_down / loss_up (telegram loss, 0..1), burst,
    seed, radio (Radio: bit rate, slot gap, overhead; default the fast one), trace (a file for
    the emulator's trace lines). `error`: the exception class its failures raise (one line,
    the kernel's message). A context manager: leaving it closes the kernel."""

    def __init__(self, stations=1, *, static=False, static_registers=123, loss_down=0.0,
                 loss_up=0.0, burst=0.0, seed=1, radio: Radio | None = None, trace=None,
                 error=CosimError):
        self.error = error
        self.lib = kernel_lib()
        radio = radio or Radio()
        self.stations = stations
        self._names = {}          # PLC id -> (name, plcharness Plc) for run_until's message
        self._keep = {}           # PLC id -> the Python scan function (kept alive)
        self._trace_cb = None
        self._end_ns = 0
        err = ctypes.create_string_buffer(256)
        self._handle = self.lib.mipcosim_new_args(
            stations, 1 if static else 0, static_registers, loss_down, loss_up, burst, seed,
            radio.bitrate, radio.slot_gap_ns, radio.overhead_bytes, err, len(err))
        if not self._handle:
            raise error(err.value.decode())
        if trace:
            try:
                self.check(self.lib.mipcosim_trace_file(self._handle, str(trace).encode()))
            except BaseException:
                self.close()
                raise

    # ------------------------------------------------------------------ state

    @property
    def handle(self):
        """The C kernel (mipcosim *); an error after close()."""
        if self._handle is None:
            raise self.error("the co-simulation is closed")
        return self._handle

    @property
    def closed(self):
        return self._handle is None

    @property
    def now(self):
        """Virtual time in ns; after close() the time it was closed at."""
        if self._handle is None:
            return self._end_ns
        return self.lib.mipcosim_now(self._handle)

    @property
    def net(self):
        """The emulator core's network (mipemu_net *) for its own API."""
        return self.lib.mipcosim_net(self.handle)

    def errmsg(self):
        return self.lib.mipcosim_errmsg(self.handle).decode()

    def check(self, rc):
        """rc of a kernel call: not 0 raises the kernel's message."""
        if rc != 0:
            raise self.error(self.errmsg())

    # ------------------------------------------------------------------ participants

    def add_plc(self, plc, tick_ns=None, name=None):
        """A plcharness Plc scanned every tick_ns (default its own task interval) from now on;
        returns its id. name: what run_until's error calls it (None: not named there)."""
        pid = self.lib.mipcosim_plc_add(self.handle, _scan_of(plc), plc.handle,
                                        tick_ns or plc.tick_ns)
        self.check(0 if pid >= 0 else -1)
        self._names[pid] = (name, plc)
        return pid

    def put_plc(self, pid, plc, tick_ns=None, name=None):
        """add_plc when pid is None (the first start), else replace (a restart); returns its id."""
        if pid is None:
            return self.add_plc(plc, tick_ns, name=name)
        self.replace(pid, plc, tick_ns, name=name)
        return pid

    def add_scan(self, fn, period_ns):
        """A participant that is not a plcrt PLC: fn (a SCAN_FN, kept alive here) called every
        period_ns of virtual time from now on; returns its id."""
        pid = self.lib.mipcosim_plc_add(self.handle, ctypes.cast(fn, ctypes.c_void_p), 1, period_ns)
        self.check(0 if pid >= 0 else -1)
        self._keep[pid] = fn
        return pid

    def replace(self, pid, plc=None, tick_ns=None, name=None):
        """PLC pid restarts as the plcharness Plc `plc` (first scan now; connect it again);
        plc None switches it off (not scanned, its modem keeps running)."""
        if plc is None:
            self.check(self.lib.mipcosim_plc_replace(self.handle, pid, None, None, 0))
            self._names.pop(pid, None)
            self._keep.pop(pid, None)
            return
        self.check(self.lib.mipcosim_plc_replace(self.handle, pid, _scan_of(plc), plc.handle,
                                                 tick_ns or plc.tick_ns))
        old = self._names.get(pid, (None, None))[0]
        self._names[pid] = (old if name is None else name, plc)

    def replace_scan(self, pid, fn, period_ns):
        """Participant pid becomes the scan function fn (see add_scan), first call now."""
        self.check(self.lib.mipcosim_plc_replace(self.handle, pid, ctypes.cast(fn, ctypes.c_void_p),
                                                 1, period_ns))
        self._names.pop(pid, None)
        self._keep[pid] = fn

    def connect(self, pid, plc, device, ep, transport="inproc"):
        """PLC pid's Modbus device `device` (of its plcharness Plc `plc`) to endpoint ep (0 =
        the MDP-810, s = station s's TRM-810): "inproc" (the runtime hands each request to the
        emulator core), "socketpair" or "tcp" (the same frames through libmodbus)."""
        if transport == "inproc":
            setter, fn = plc.library.plcrt_device_set_transport, self.lib.mipcosim_connect_inproc
        elif transport in TRANSPORTS:
            setter = plc.library.plcrt_device_set_fd
            fn = self.lib.mipcosim_connect if transport == "socketpair" else self.lib.mipcosim_connect_tcp
        else:
            raise self.error(f"transport {transport!r}: use inproc, socketpair or tcp")
        dev = device if isinstance(device, bytes) else device.encode()
        self.check(fn(self.handle, pid, ctypes.cast(setter, ctypes.c_void_p), dev, ep))

    def request(self, ep, adu: bytes, rsp):
        """One Modbus TCP request frame of a participant that is not a plcrt PLC to endpoint ep
        at the current virtual time (mipcosim_request); the response's length in rsp (a
        ctypes buffer), or -1."""
        return self.lib.mipcosim_request(self.handle, ep, adu, len(adu), rsp, len(rsp))

    # ------------------------------------------------------------------ observing

    def tap(self, slot, pid, seq, hdr, nhdr, len_index=-1, data=None, ndata_max=0):
        """mipcosim_tap: after each scan of pid, an entry when the word at seq changed."""
        self.check(self.lib.mipcosim_tap(self.handle, slot, pid, seq, hdr, nhdr, len_index, data,
                                         ndata_max))

    def read_taps(self):
        """The taps' entries since the last call: (slot, PLC id, words)."""
        return read_taps(self.lib, self.handle)

    def on_trace(self, fn):
        """fn(line: dict) for every trace line of the emulator core (None: off)."""
        self._trace_cb = None if fn is None else TRACE_FN(
            lambda user, line, n: fn(json.loads(ctypes.string_at(line, n))))
        self.lib.mipemu_net_set_trace(self.net, self._trace_cb, None)

    def radio_stats(self, stations=None):
        """The emulator's radio counters summed over `stations` (default all), and the
        kernel's scans and Modbus requests."""
        return radio_stats(self.lib, self.handle, stations or range(1, self.stations + 1))

    def failed(self):
        """(name, plcharness Plc) of the PLC whose scan failed the last run, or None."""
        return self._names.get(self.lib.mipcosim_failed_plc(self.handle))

    # ------------------------------------------------------------------ running

    def run_until(self, t_ns):
        """Scan every participant due and run the radio up to virtual time t_ns. A failure
        raises the kernel's message, with the failed PLC's name and its runtime's reason."""
        if self.lib.mipcosim_run(self.handle, t_ns) != 0:
            raise self.error(self.failure())

    def failure(self):
        """The message of a failed run: the kernel's, then the failed PLC's name and reason."""
        msg = self.errmsg()
        failed = self.failed()
        if failed is not None and failed[0] is not None:
            name, plc = failed
            why = plc.library.plcrt_errmsg(plc.handle) or b""
            msg += f": {name}: {why.decode()}"
        return msg

    def run_for(self, ns):
        self.run_until(self.now + ns)

    def close(self):
        """Frees the kernel (the caller closes its PLCs); again: nothing."""
        if self._handle is not None:
            self._end_ns = self.lib.mipcosim_now(self._handle)
            self.lib.mipcosim_free(self._handle)
            self._handle = None
            self._keep = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _scan_of(plc):
    return ctypes.cast(plc.library.plcrt_scan, ctypes.c_void_p)

