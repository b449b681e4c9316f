"""Plc: one built program loaded into this process (ctypes), stepped in virtual time."""
from __future__ import annotations

import ctypes
import itertools
import os
import re
import shutil
import tempfile
from pathlib import Path

from .build import BuildError, BuildResult, build_program, is_openplc_config


class PlcError(Exception):
    """Bad path or value, a config error, or a runtime error of the core."""


_TYPES = {
    "BOOL": ctypes.c_uint8, "BYTE": ctypes.c_uint8, "USINT": ctypes.c_uint8,
    "SINT": ctypes.c_int8, "WORD": ctypes.c_uint16, "UINT": ctypes.c_uint16,
    "INT": ctypes.c_int16, "DWORD": ctypes.c_uint32, "UDINT": ctypes.c_uint32,
    "DINT": ctypes.c_int32, "LWORD": ctypes.c_uint64, "ULINT": ctypes.c_uint64,
    "LINT": ctypes.c_int64, "REAL": ctypes.c_float, "LREAL": ctypes.c_double,
}
_TIME_TYPES = {"TIME", "DATE", "TOD", "DT", "TIME_OF_DAY", "DATE_AND_TIME"}
_LOCATED_SIZE = {"X": ctypes.c_uint8, "B": ctypes.c_uint8, "W": ctypes.c_uint16,
                 "D": ctypes.c_uint32, "L": ctypes.c_uint64}


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Var:
    """Storage of one variable (or array element) at a C address."""

    def __init__(self, name, type_name, addr, dims=()):
        self.name = name
        self.type = type_name           # elementary, TIME-like or ENUM:...
        self.addr = addr
        self.dims = dims                # ((lo, hi), ...) for arrays

    @property
    def ctype(self):
        if self.type in _TIME_TYPES:
            return _Timespec
        if self.type.startswith("ENUM:"):
            return ctypes.c_int
        return _TYPES[self.type]

    def _count(self):
        n = 1
        for lo, hi in self.dims:
            n *= hi - lo + 1
        return n

    def size(self):
        return ctypes.sizeof(self.ctype) * self._count()

    def _get1(self, addr):
        obj = self.ctype.from_address(addr)
        if self.type in _TIME_TYPES:
            return obj.tv_sec * 1_000_000_000 + obj.tv_nsec
        if self.type == "BOOL":
            return bool(obj.value)
        return obj.value

    def _encode1(self, value):
        """Bytes of one element, with a range check."""
        t = self.type
        if t in _TIME_TYPES:
            if not isinstance(value, int) or isinstance(value, bool):
                raise PlcError(f"{self.name}: {t} takes an int of nanoseconds, not {value!r}")
            sec, nsec = divmod(value, 1_000_000_000)
            return bytes(_Timespec(sec, nsec))
        ct = self.ctype
        if t in ("REAL", "LREAL"):
            if not isinstance(value, (int, float)) or isinstance(value, bool):
                raise PlcError(f"{self.name}: {t} takes a number, not {value!r}")
            return bytes(ct(float(value)))
        if isinstance(value, bool):
            value = int(value)
        if not isinstance(value, int):
            raise PlcError(f"{self.name}: {t} takes an int, not {value!r}")
        if t == "BOOL":
            if value not in (0, 1):
                raise PlcError(f"{self.name}: BOOL takes True/False or 0/1, not {value}")
        else:
            bits = ctypes.sizeof(ct) * 8
            signed = ct(-1).value < 0
            lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
            if not lo <= value <= hi:
                raise PlcError(f"{self.name}: {value} is out of range for {t} ({lo}..{hi})")
        return bytes(ct(value))

    def read(self):
        if not self.dims:
            return self._get1(self.addr)
        step = ctypes.sizeof(self.ctype)
        flat = [self._get1(self.addr + i * step) for i in range(self._count())]
        return _nest(flat, [hi - lo + 1 for lo, hi in self.dims])

    def encode(self, value):
        if not self.dims:
            return self._encode1(value)
        flat = list(_flatten(value))
        if len(flat) != self._count():
            raise PlcError(f"{self.name}: needs {self._count()} values, got {len(flat)}")
        return b"".join(self._encode1(v) for v in flat)

    def element(self, indexes):
        if len(indexes) != len(self.dims):
            raise PlcError(f"{self.name}: needs {len(self.dims)} index(es), got {len(indexes)}")
        off = 0
        for i, (lo, hi) in zip(indexes, self.dims):
            if not lo <= i <= hi:
                raise PlcError(f"{self.name}: index {i} outside {lo}..{hi}")
            off = off * (hi - lo + 1) + (i - lo)
        idx = ",".join(map(str, indexes))
        return _Var(f"{self.name}[{idx}]", self.type, self.addr + off * ctypes.sizeof(self.ctype))


def _nest(flat, shape):
    if len(shape) == 1:
        return flat
    n = len(flat) // shape[0]
    return [_nest(flat[i * n:(i + 1) * n], shape[1:]) for i in range(shape[0])]


def _flatten(value):
    if isinstance(value, (list, tuple)):
        for v in value:
            yield from _flatten(v)
    else:
        yield value


_ARRAY_RE = re.compile(r"^(\w+(?::\w+)?)\[([-0-9.,\s]+)\]$")
_ADDR_RE = re.compile(r"^%?([IQM])([XBWDL])(\d+)(?:\.(\d+))?$", re.I)
_load_counter = itertools.count()


def _parse_type(type_str):
    m = _ARRAY_RE.match(type_str)
    if not m:
        return type_str, ()
    dims = []
    for part in m.group(2).split(","):
        lo, hi = part.split("..")
        dims.append((int(lo), int(hi)))
    return m.group(1), tuple(dims)


class Plc:
    """A program built from ST and loaded into this process; see docs/runtime-harness.md."""

    def __init__(self, result: BuildResult, workdir: Path, config=None):
        self.build_result = result
        # One copy of the library per Plc: a program's state lives in C globals, and the
        # dynamic loader shares one loaded file between all who open it.
        n = next(_load_counter)
        self._libpath = Path(workdir) / f"libplc-{os.getpid()}-{n}.so"
        shutil.copyfile(result.library, self._libpath)
        lib = self._lib = ctypes.CDLL(str(self._libpath))
        lib.plcrt_linked_program.restype = ctypes.c_void_p
        lib.plcrt_new.restype = ctypes.c_void_p
        lib.plcrt_new.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t]
        for name, res, args in [
            ("plcrt_errmsg", ctypes.c_char_p, [ctypes.c_void_p]),
            ("plcrt_image", ctypes.c_void_p, [ctypes.c_void_p]),
            ("plcrt_time_ns", ctypes.c_uint64, [ctypes.c_void_p]),
            ("plcrt_tick_ns", ctypes.c_uint64, [ctypes.c_void_p]),
            ("plcrt_scan_count", ctypes.c_uint64, [ctypes.c_void_p]),
            ("plcrt_scan", ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint64]),
            ("plcrt_run_realtime", ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint64,
                                                  ctypes.c_void_p]),
            ("plcrt_rt_stats", None, [ctypes.c_void_p, ctypes.c_void_p]),
            ("plcrt_load_config", ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]),
            ("plcrt_force", ctypes.c_int, [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_char_p,
                                           ctypes.c_size_t]),
            ("plcrt_unforce", ctypes.c_int, [ctypes.c_void_p, ctypes.c_void_p]),
            ("plcrt_symbol_addr", ctypes.c_void_p, [ctypes.c_void_p, ctypes.c_size_t]),
            ("plcrt_image_locate", ctypes.c_void_p, [ctypes.c_void_p, ctypes.c_char, ctypes.c_char,
                                                     ctypes.POINTER(ctypes.c_long), ctypes.c_int,
                                                     ctypes.c_char_p, ctypes.c_size_t]),
            ("plcrt_slave_start", ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]),
            ("plcrt_slave_port", ctypes.c_int, [ctypes.c_void_p]),
            ("plcrt_device_count", ctypes.c_int, [ctypes.c_void_p]),
            ("plcrt_device_name", ctypes.c_char_p, [ctypes.c_void_p, ctypes.c_int]),
            ("plcrt_device_stats", ctypes.c_int, [ctypes.c_void_p, ctypes.c_int,
                                                  ctypes.POINTER(ctypes.c_uint64),
                                                  ctypes.POINTER(ctypes.c_uint64),
                                                  ctypes.POINTER(ctypes.c_uint64)]),
            ("plcrt_device_dropped_replies", ctypes.c_uint64, [ctypes.c_void_p, ctypes.c_int]),
            ("plcrt_device_set_fd", ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int,
                                                   ctypes.c_void_p, ctypes.c_void_p]),
            ("plcrt_free", None, [ctypes.c_void_p]),
            ("plcrt_retain_count", ctypes.c_size_t, [ctypes.c_void_p]),
            ("plcrt_retain_snapshot_size", ctypes.c_size_t, [ctypes.c_void_p]),
            ("plcrt_retain_save_to", ctypes.c_size_t, [ctypes.c_void_p, ctypes.c_char_p,
                                                       ctypes.c_size_t]),
            ("plcrt_retain_load_from", ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p,
                                                      ctypes.c_size_t]),
            ("plcrt_retain_set_memory", ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint64]),
            ("plcrt_retain_last", ctypes.c_size_t, [ctypes.c_void_p, ctypes.c_char_p,
                                                    ctypes.c_size_t]),
            ("plcrt_retain_saves", ctypes.c_uint64, [ctypes.c_void_p]),
            ("plcrt_retain_failures", ctypes.c_uint64, [ctypes.c_void_p]),
        ]:
            fn = getattr(lib, name)
            fn.restype = res
            fn.argtypes = args
        err = ctypes.create_string_buffer(512)
        self._rt = lib.plcrt_new(lib.plcrt_linked_program(), err, len(err))
        if not self._rt:
            raise PlcError(err.value.decode())
        self._forced = {}
        self._vars = {}
        self._aliases = {}
        self._index_symbols(result)
        if config is not None:
            if lib.plcrt_load_config(self._rt, str(config).encode()) != 0:
                raise PlcError(self._err())

    # ------------------------------------------------------------ construction

    @classmethod
    def build(cls, sources, workdir=None, compiler="auto", config=None,
              semantics=None) -> "Plc":
        """Translate and link the ST sources, load the program, run config_init__.
        config: a plcrt config (or OpenPLC mbconfig.cfg) whose Modbus master runs in the
        same virtual time. semantics: stc --semantics (matiec, openplc, iec); by default
        PLCRT_SEMANTICS, else openplc with an OpenPLC mbconfig.cfg (the program is meant for
        OpenPLC, whose matiec fork computes some values differently), else stc's default."""
        if semantics is None and not os.environ.get("PLCRT_SEMANTICS") and config is not None \
                and is_openplc_config(config):
            semantics = "openplc"
        if workdir is None:
            workdir = Path(tempfile.mkdtemp(prefix="plcharness-"))
        workdir = Path(workdir)
        workdir.mkdir(parents=True, exist_ok=True)
        result = build_program(sources, workdir / "plc-build", compiler=compiler,
                               semantics=semantics)
        return cls(result, workdir, config=config)

    def _err(self):
        return (self._lib.plcrt_errmsg(self._rt) or b"").decode()

    def _index_symbols(self, result):
        full = {}
        for i, s in enumerate(result.symbols):
            base, dims = _parse_type(s.type)
            if base not in _TYPES and base not in _TIME_TYPES and not base.startswith("ENUM:"):
                continue  # STRING and other types the harness does not decode
            addr = self._lib.plcrt_symbol_addr(self._rt, i)
            if not addr:
                continue
            full[s.path] = _Var(s.path, base, addr, dims)
        self._vars = full
        aliases = {}

        def add(alias, path):
            aliases.setdefault(alias, set()).add(path)

        by_type = {}
        for inst, ptype in result.programs.items():
            by_type.setdefault(ptype, []).append(inst)
        for path in full:
            add(path, path)
            parts = path.split(".")
            for k in range(1, len(parts)):
                prefix = ".".join(parts[:k])
                rest = ".".join(parts[k:])
                if k <= 3:
                    add(rest, path)  # RES0.INSTANCE0.X, INSTANCE0.X, X (for globals)
                if prefix in result.programs:
                    add(f"{result.programs[prefix]}.{rest}", path)
        self._aliases = {a: p for a, p in aliases.items()}

    # ------------------------------------------------------------ lookup

    def _lookup(self, name: str) -> _Var:
        if not isinstance(name, str):
            raise PlcError(f"variable name must be a str, not {name!r}")
        key = name.strip().upper()
        m = _ADDR_RE.match(key)
        if m:
            return self._located(m)
        indexes = None
        im = re.match(r"^(.*)\[([-0-9,\s]+)\]$", key)
        if im:
            key = im.group(1).strip()
            indexes = [int(x) for x in im.group(2).split(",")]
        paths = self._aliases.get(key)
        if not paths:
            raise PlcError(f"no variable {name!r} in the program")
        if len(paths) > 1:
            raise PlcError(f"{name!r} is ambiguous: {', '.join(sorted(paths))}")
        var = self._vars[next(iter(paths))]
        if indexes is not None:
            if not var.dims:
                raise PlcError(f"{name!r}: {var.name} is not an array")
            var = var.element(indexes)
        return var

    def _located(self, m) -> _Var:
        area, size = m.group(1), m.group(2)
        parts = [int(m.group(3))] + ([int(m.group(4))] if m.group(4) is not None else [])
        arr = (ctypes.c_long * len(parts))(*parts)
        err = ctypes.create_string_buffer(256)
        addr = self._lib.plcrt_image_locate(self._lib.plcrt_image(self._rt), area.encode(),
                                            size.encode(), arr, len(parts), err, len(err))
        if not addr:
            raise PlcError(err.value.decode())
        type_name = {"X": "BOOL", "B": "BYTE", "W": "WORD", "D": "DWORD", "L": "LWORD"}[size]
        return _Var(m.group(0), type_name, addr)

    def address(self, name) -> int:
        """C address of a variable or located address in this process (for C code that
        reads it directly, e.g. a co-simulation); valid while the Plc is open."""
        return self._lookup(name).addr

    @property
    def library(self) -> ctypes.CDLL:
        """This Plc's own copy of the program library (plcrt_* functions)."""
        return self._lib

    @property
    def handle(self) -> int:
        """The plcrt_t * of this Plc, for calling the C API (include/plcrt.h) directly."""
        return self._rt

    def variables(self):
        """Full IEC paths of every variable the harness can read."""
        return sorted(self._vars)

    # ------------------------------------------------------------ access

    def __getitem__(self, name):
        return self._lookup(name).read()

    def __setitem__(self, name, value):
        var = self._lookup(name)
        data = var.encode(value)
        ctypes.memmove(var.addr, data, len(data))

    def force(self, name, value):
        """Hold name at value before and after the program, every scan, until unforced."""
        var = self._lookup(name)
        data = var.encode(value)
        # the core forces up to 16 bytes at a time: split arrays into elements
        step = ctypes.sizeof(var.ctype)
        keys = []
        for off in range(0, len(data), step):
            if self._lib.plcrt_force(self._rt, var.addr + off, data[off:off + step], step) != 0:
                raise PlcError(self._err())
            keys.append(var.addr + off)
        self._forced[var.name] = keys

    def unforce(self, name):
        var = self._lookup(name)
        keys = self._forced.pop(var.name, None)
        if keys is None:
            raise PlcError(f"{name!r} is not forced")
        for addr in keys:
            self._lib.plcrt_unforce(self._rt, addr)

    # ------------------------------------------------------------ retain

    def retain_count(self) -> int:
        """Number of retained variables (stc's RETAIN.c; for matiec builds the table
        plcrt-build generates: what matiec marks retained and the arrays it cannot mark)."""
        return self._lib.plcrt_retain_count(self._rt)

    def retain_save(self) -> bytes:
        """A snapshot of the retained variables (the format of plcrt's retain file)."""
        buf = ctypes.create_string_buffer(self._lib.plcrt_retain_snapshot_size(self._rt))
        n = self._lib.plcrt_retain_save_to(self._rt, buf, len(buf))
        if n == 0:
            raise PlcError(self._err())
        return buf.raw[:n]

    def retain_load(self, data: bytes):
        """Restore a snapshot (a warm start of a freshly initialised program); PlcError with
        one line when it is damaged or of another set of retained variables."""
        if self._lib.plcrt_retain_load_from(self._rt, bytes(data), len(data)) != 0:
            raise PlcError(self._err())

    def retain_in_memory(self, period_ns: int):
        """Take snapshots as the runtime does (every period_ns of scan time, 0: never, and
        whenever the config's [retain] request bit is TRUE after a scan), but into memory
        instead of a file; retain_last() returns the last complete one."""
        if self._lib.plcrt_retain_set_memory(self._rt, period_ns) != 0:
            raise PlcError(self._err())

    def retain_last(self):
        """The last complete in-memory snapshot (bytes), or None when none was taken yet."""
        buf = ctypes.create_string_buffer(self._lib.plcrt_retain_snapshot_size(self._rt))
        n = self._lib.plcrt_retain_last(self._rt, buf, len(buf))
        return buf.raw[:n] if n else None

    @property
    def retain_saves(self) -> int:
        """Snapshots completed since this start (what [retain] saved shows, mod 65536)."""
        return self._lib.plcrt_retain_saves(self._rt)

    @property
    def retain_failures(self) -> int:
        return self._lib.plcrt_retain_failures(self._rt)

    # ------------------------------------------------------------ time

    def scan(self, n: int = 1):
        """Run n scans in virtual time (I/O phase, program, time += tick)."""
        if n < 0:
            raise PlcError("scan count must be >= 0")
        if self._lib.plcrt_scan(self._rt, n) != 0:
            raise PlcError(self._err())

    def run_realtime(self, n: int) -> dict:
        """Run n scans in real time (absolute deadlines on the monotonic clock, the Modbus
        master in its own thread). After this the Plc cannot go back to virtual scans.
        Returns {"scans", "overruns", "max_late_ns", "max_scan_ns"}."""
        if n < 1:
            raise PlcError("real-time scan count must be >= 1")
        if self._lib.plcrt_run_realtime(self._rt, n, None) != 0:
            raise PlcError(self._err())
        stats = (ctypes.c_uint64 * 4)()
        self._lib.plcrt_rt_stats(self._rt, stats)
        return dict(zip(("scans", "overruns", "max_late_ns", "max_scan_ns"), stats))

    def run_for(self, ns: int):
        """Scan until at least ns nanoseconds of virtual time have passed."""
        tick = self.tick_ns
        self.scan(-(-ns // tick))

    @property
    def time_ns(self) -> int:
        return self._lib.plcrt_time_ns(self._rt)

    @property
    def tick_ns(self) -> int:
        return self._lib.plcrt_tick_ns(self._rt)

    @property
    def scans(self) -> int:
        return self._lib.plcrt_scan_count(self._rt)

    # ------------------------------------------------------------ Modbus

    def start_slave(self, port=0, host="127.0.0.1") -> int:
        """Serve the image as a Modbus TCP slave (served during each scan's I/O phase).
        Returns the port (port 0 picks a free one)."""
        if self._lib.plcrt_slave_start(self._rt, host.encode(), port) != 0:
            raise PlcError(self._err())
        return self._lib.plcrt_slave_port(self._rt)

    @property
    def slave_port(self) -> int:
        """The port the slave listens on (a config's [slave] with port = 0 picks a free one);
        0 without a slave."""
        return self._lib.plcrt_slave_port(self._rt)

    def device_stats(self):
        """{device name: {"errors": n, "requests": n, "connects": n, "dropped_replies": n}} of
        the Modbus master (dropped: replies with the transaction id of an earlier request)."""
        out = {}
        for i in range(self._lib.plcrt_device_count(self._rt)):
            e, r, c = ctypes.c_uint64(), ctypes.c_uint64(), ctypes.c_uint64()
            self._lib.plcrt_device_stats(self._rt, i, ctypes.byref(e), ctypes.byref(r),
                                         ctypes.byref(c))
            name = self._lib.plcrt_device_name(self._rt, i).decode()
            out[name] = {"errors": e.value, "requests": r.value, "connects": c.value,
                         "dropped_replies": self._lib.plcrt_device_dropped_replies(self._rt, i)}
        return out

    _AFTER_SEND = ctypes.CFUNCTYPE(None, ctypes.c_void_p)

    def set_device_fd(self, device: str, fd: int, after_send=None):
        """Transport seam (interfaces.md §2): the config's device talks over fd (one end of a
        socketpair) instead of TCP; after_send() is called after each request is sent, before
        the reply is read, so an in-process peer can answer in lockstep. Call before the
        first scan; the fd stays the caller's."""
        cb = self._AFTER_SEND(lambda _user: after_send()) if after_send else None
        self._keep_alive = getattr(self, "_keep_alive", []) + [cb]  # ctypes must not free it
        cb_ptr = ctypes.cast(cb, ctypes.c_void_p) if cb else None
        if self._lib.plcrt_device_set_fd(self._rt, device.encode(), fd, cb_ptr, None) != 0:
            raise PlcError(self._err())

    def close(self):
        if getattr(self, "_rt", None):
            self._lib.plcrt_free(self._rt)
            self._rt = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown: the library may be gone already
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


__all__ = ["Plc", "PlcError", "BuildError"]
