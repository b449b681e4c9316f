"""A device of a plcrt PLC answered by Python, in virtual time: the runtime's in-process
transport (plcrt_device_set_transport, the seam mipcosim_connect_inproc uses for the modems)
hands each request ADU of the device to a Python function during the scan, and its answer
goes back through the same Modbus code as over TCP. Issue 35: the control-system stand-ins
(peers/mippeer/unicos.py's UnicosDriver.handle) as devices of the central PLC, alone
(plcharness) or inside the co-simulation (the PLC added with mipcosim_plc_add).

    dev = PyDevice(plc, "unicos", driver.handle)    # before the PLC's first scan
    ...                                             # scans; dev.check() raises what the
                                                    # handler raised
"""
from __future__ import annotations

import ctypes

from .sim import CosimError

TRANSACT = ctypes.CFUNCTYPE(ctypes.c_long, ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint8),
                            ctypes.c_size_t, ctypes.POINTER(ctypes.c_uint8), ctypes.c_size_t)


class PyDevice:
    """Wires `device` of `plc` (a plcharness Plc, before its first scan) to `handler(adu) ->
    bytes | None`: the request ADU (MBAP header + PDU) in, the response ADU out, None for no
    answer (the runtime sees a timeout: status 1110). An exception in the handler is kept
    (`check()` raises it) and the request gets no answer."""

    def __init__(self, plc, device: str, handler):
        self.handler = handler
        self.requests = 0                 # answered requests
        self.unanswered = 0               # requests the handler did not answer
        self._error = None
        self._cb = TRANSACT(self._transact)   # referenced as long as the device lives
        fn = plc.library.plcrt_device_set_transport
        fn.argtypes = [ctypes.c_void_p, ctypes.c_char_p, TRANSACT, ctypes.c_void_p]
        fn.restype = ctypes.c_int
        if fn(plc.handle, device.encode(), self._cb, None) != 0:
            raise CosimError(f"device {device!r}: the runtime refused the transport "
                             f"(no such device in the config, or the PLC has scanned already)")
        self._plc = plc                   # the runtime holds self._cb: keep both together

    def _transact(self, _user, req, req_len, rsp, cap):
        try:
            out = self.handler(ctypes.string_at(req, req_len))
            if out is None or len(out) > cap:
                self.unanswered += 1
                return -1
            ctypes.memmove(rsp, out, len(out))
            self.requests += 1
            return len(out)
        except BaseException as e:        # raised again by check(), not into the C caller
            self._error = self._error or e
            self.unanswered += 1
            return -1

    def check(self):
        if self._error:
            e, self._error = self._error, None
            raise e
