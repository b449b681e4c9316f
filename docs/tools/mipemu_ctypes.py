"""The emulator core (emulator/include/mipemu.h) loaded through ctypes, in virtual time.

The emulator core is the one in the simulation kernel, build/cosim/libmipcosim.so (cosim/part.mk
links emulator/src/mipemu.c into it): the same code the mip-emulator server and the
co-simulation run, not a second build of it.
"""
from __future__ import annotations

import ctypes
import struct
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SO = REPO / "build" / "cosim" / "libmipcosim.so"

TRACE_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t)


class Config(ctypes.Structure):
    _fields_ = [("stations", ctypes.c_int), ("mode", ctypes.c_int),
                ("static_registers", ctypes.c_int), ("loss_down", ctypes.c_double),
                ("loss_up", ctypes.c_double), ("burst", ctypes.c_double),
                ("seed", ctypes.c_uint64), ("bitrate", ctypes.c_uint32),
                ("slot_gap_ns", ctypes.c_uint64), ("overhead_bytes", ctypes.c_int),
                ("fail_polls", ctypes.c_int), ("allow_127", ctypes.c_int),
                ("lose_record", ctypes.c_int)]


class Stats(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint64) for n in (
        "polls", "tel_down", "lost_down", "tel_up", "lost_up", "blocks_down", "blocks_up",
        "dup_down", "dup_up", "confirmed_down", "confirmed_up")]


class EmuError(RuntimeError):
    pass


def _lib():
    if not SO.exists():
        raise EmuError(f"{SO.relative_to(REPO)} missing: run `make {SO.relative_to(REPO)}` (or `make`)")
    lib = ctypes.CDLL(str(SO))
    lib.mipemu_config_default.argtypes = [ctypes.POINTER(Config)]
    lib.mipemu_net_new.restype = ctypes.c_void_p
    lib.mipemu_net_new.argtypes = [ctypes.POINTER(Config), ctypes.c_char_p, ctypes.c_size_t]
    lib.mipemu_net_free.argtypes = [ctypes.c_void_p]
    lib.mipemu_net_set_trace.argtypes = [ctypes.c_void_p, TRACE_FN, ctypes.c_void_p]
    lib.mipemu_net_advance.argtypes = [ctypes.c_void_p, ctypes.c_uint64]
    lib.mipemu_net_advance.restype = ctypes.c_int
    lib.mipemu_handle.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_size_t,
                                  ctypes.c_char_p, ctypes.c_size_t]
    lib.mipemu_handle.restype = ctypes.c_long
    lib.mipemu_net_stats.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(Stats)]
    return lib


class Net:
    """One emulated network; `lines` collects the JSON trace lines (str, newline stripped)."""

    def __init__(self, **cfg):
        self.lib = _lib()
        c = Config()
        self.lib.mipemu_config_default(ctypes.byref(c))
        for k, v in cfg.items():
            if k == "slot_gap_ms":
                c.slot_gap_ns = int(v * 1_000_000)
            else:
                setattr(c, k, v)
        err = ctypes.create_string_buffer(200)
        self.net = self.lib.mipemu_net_new(ctypes.byref(c), err, 200)
        if not self.net:
            raise EmuError(err.value.decode())
        self.lines: list[str] = []
        self._cb = TRACE_FN(lambda user, line, n: self.lines.append(
            ctypes.string_at(line, n).decode().rstrip("\n")))
        self.lib.mipemu_net_set_trace(self.net, self._cb, None)
        self._tid = 0
        self._out = ctypes.create_string_buffer(400)

    def close(self):
        if self.net:
            self.lib.mipemu_net_free(self.net)
            self.net = None

    def advance(self, t_ns):
        if self.lib.mipemu_net_advance(self.net, t_ns) != 0:
            raise EmuError("time went backwards")

    def _request(self, ep, unit, pdu):
        self._tid = (self._tid + 1) & 0xFFFF
        frame = struct.pack(">HHHB", self._tid, 0, len(pdu) + 1, unit) + pdu
        n = self.lib.mipemu_handle(self.net, ep, frame, len(frame), self._out, 400)
        if n < 0:
            raise EmuError("connection closed by the emulator")
        resp = self._out.raw[:n]
        fc = resp[7]
        if fc & 0x80:
            return None, resp[8]
        return resp[8:], 0

    def read(self, ep, unit, addr, qty):
        """FC3; returns (registers, 0) or (None, exception code)."""
        body, exc = self._request(ep, unit, struct.pack(">BHH", 3, addr, qty))
        if body is None:
            return None, exc
        return list(struct.unpack(f">{qty}H", body[1:1 + 2 * qty])), 0

    def write(self, ep, unit, addr, regs):
        """FC16; returns 0 or the exception code."""
        pdu = struct.pack(f">BHHB{len(regs)}H", 16, addr, len(regs), 2 * len(regs), *regs)
        body, exc = self._request(ep, unit, pdu)
        return exc

    def stats(self, station=1):
        s = Stats()
        self.lib.mipemu_net_stats(self.net, station, ctypes.byref(s))
        return {n: getattr(s, n) for n, _ in Stats._fields_}
