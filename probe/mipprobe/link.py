"""The probe's Modbus side: an endpoint (Modbus TCP `HOST[:PORT]` or RTU `rtu:DEVICE[:BAUD[:FRAME]]`,
either with `@UNIT`), its requests through pymodbus, every request traced, every failure one line.

The trace is the emulator's format (emulator/README.md "Trace format": one JSON object a line,
`t` in ns since the probe started, `seq`, `ev`), so `mip-view --follow` and the kit's readers
read it: an `ev: "modbus"` line per request the probe made (with `"src": "mip-probe"`) and an
`ev: "probe"` line per check result.
"""
from __future__ import annotations

import json
import logging
import socket
import time

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusException
from pymodbus.framer import FramerType

# pymodbus logs connection failures itself; the probe reports them once, in its own words.
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)

EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value",
              4: "server device failure", 6: "server device busy",
              10: "gateway path unavailable", 11: "gateway target device failed to respond"}


class SpecError(ValueError):
    """A bad endpoint on the command line."""


class NoLink(Exception):
    """The endpoint cannot be reached or does not answer (one line, no traceback)."""


class ModbusExc(Exception):
    """The endpoint answered with a Modbus exception."""

    def __init__(self, code, what):
        self.code = code
        super().__init__(f"{what}: exception {code:02X} ({EXCEPTIONS.get(code, 'unknown')})")


def parse_spec(spec: str, default_unit: int | None):
    """`HOST[:PORT][@UNIT]` (Modbus TCP, port 502 by default) or
    `rtu:DEVICE[:BAUD[:FRAME]][@UNIT]` (BAUD 19200, FRAME 8E1 by default)."""
    unit = default_unit
    if "@" in spec:
        spec, u = spec.rsplit("@", 1)
        if not u.isdigit() or not 0 <= int(u) <= 247:
            raise SpecError(f"{spec}@{u}: the unit id must be 0..247")
        unit = int(u)
    if spec.startswith("rtu:"):
        parts = spec[4:].split(":")
        dev = parts[0]
        if not dev:
            raise SpecError(f"{spec}: rtu:DEVICE[:BAUD[:FRAME]] needs a serial device")
        baud = parts[1] if len(parts) > 1 else "19200"
        frame = parts[2].upper() if len(parts) > 2 else "8E1"
        if len(parts) > 3 or not baud.isdigit() or not (len(frame) == 3 and frame[0] in "78"
                                                         and frame[1] in "NEO" and frame[2] in "12"):
            raise SpecError(f"{spec}: rtu:DEVICE[:BAUD[:FRAME]], e.g. rtu:/dev/ttyUSB0:19200:8E1")
        return {"kind": "rtu", "device": dev, "baud": int(baud), "frame": frame, "unit": unit}
    host, port = spec, "502"
    if spec.count(":") == 1:
        host, port = spec.split(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise SpecError(f"{spec}: HOST[:PORT] (Modbus TCP) or rtu:DEVICE[:BAUD[:FRAME]]")
    return {"kind": "tcp", "host": host, "port": int(port), "unit": unit}


def spec_text(s):
    if s["kind"] == "tcp":
        return f"{s['host']}:{s['port']}"
    return f"rtu:{s['device']}:{s['baud']}:{s['frame']}" + (f"@{s['unit']}" if s["unit"] else "")


def _serial_reason(s):
    """why pyserial cannot open the device as pymodbus asks (pymodbus only says it failed)"""
    import serial
    try:
        serial.serial_for_url(s["device"], baudrate=s["baud"], bytesize=int(s["frame"][0]),
                              parity=s["frame"][1], stopbits=int(s["frame"][2])).close()
    except Exception as e:      # pyserial raises termios and OS errors as they come
        return str(getattr(e, "strerror", None) or e)
    return (f"pymodbus could not open it as {s['frame']}: another program has it open, or it "
            f"is a pty (the emulator's line), where pymodbus takes only 8N1 (docs/serial.md, "
            f"parity on a pty)")


class Tracer:
    """The trace file, written line by line as the probe runs (flushed: a follower sees it)."""

    def __init__(self, path=None):
        self.t0 = time.monotonic_ns()
        self.seq = 0
        self.f = open(path, "w", encoding="utf-8") if path else None

    def now(self):
        return time.monotonic_ns() - self.t0

    def line(self, **d):
        if self.f is None:
            return
        self.f.write(json.dumps({"t": self.now(), "seq": self.seq, **d}) + "\n")
        self.f.flush()
        self.seq += 1

    def close(self):
        if self.f:
            self.f.close()
            self.f = None


_SERIAL = {}      # one client per serial device: endpoints on one line share it


class Endpoint:
    """One modem endpoint: `ep` "mdp" or "trm", its station, the unit id of its requests."""

    def __init__(self, spec: dict, ep: str, station: int, unit: int, tracer: Tracer,
                 timeout: float = 1.0):
        self.spec, self.ep, self.station, self.unit = spec, ep, station, unit
        self.tracer, self.timeout = tracer, timeout
        self.text = spec_text(spec)
        self.client = None
        self.latencies = []            # s per answered request

    @property
    def name(self):
        return "MDP" if self.ep == "mdp" else "TRM"

    def _connect(self):
        if self.client is not None:
            return
        s = self.spec
        if s["kind"] == "tcp":
            try:    # what pymodbus would only report as "failed": the reason, in one line
                socket.create_connection((s["host"], s["port"]), timeout=self.timeout).close()
            except ConnectionRefusedError:
                raise NoLink(f"{self.name} {self.text}: connection refused (nothing listens on "
                             f"that port: the modem's Modbus TCP port, note §1)") from None
            except socket.timeout:
                raise NoLink(f"{self.name} {self.text}: no answer to the connection within "
                             f"{self.timeout:g} s (address unreachable or filtered)") from None
            except socket.gaierror as e:
                raise NoLink(f"{self.name} {self.text}: unknown host ({e.strerror})") from None
            except OSError as e:
                raise NoLink(f"{self.name} {self.text}: {e.strerror or e}") from None
            self.client = ModbusTcpClient(s["host"], port=s["port"], timeout=self.timeout,
                                          retries=0)
            if not self.client.connect():
                self.client = None
                raise NoLink(f"{self.name} {self.text}: cannot connect")
            return
        key = s["device"]
        if key not in _SERIAL:
            c = ModbusSerialClient(s["device"], framer=FramerType.RTU, baudrate=s["baud"],
                                   bytesize=int(s["frame"][0]), parity=s["frame"][1],
                                   stopbits=int(s["frame"][2]), timeout=self.timeout, retries=0)
            if not c.connect():
                raise NoLink(f"{self.name} {self.text}: cannot open the serial device: "
                             f"{_serial_reason(s)}")
            _SERIAL[key] = c
        self.client = _SERIAL[key]

    def close(self):
        if self.client is not None and self.spec["kind"] == "tcp":
            self.client.close()
        self.client = None

    def _call(self, what, fn, trace):
        self._connect()
        t = time.monotonic()
        try:
            r = fn()
        except ModbusException:
            self.close()
            self.tracer.line(ev="modbus", src="mip-probe", ep=self.ep, st=self.station,
                             unit=self.unit, **trace, exc=-1)
            raise NoLink(f"{self.name} {self.text}: no answer to {what} within "
                         f"{self.timeout:g} s") from None
        self.latencies.append(time.monotonic() - t)
        exc = r.exception_code if r.isError() and hasattr(r, "exception_code") else 0
        self.tracer.line(ev="modbus", src="mip-probe", ep=self.ep, st=self.station,
                         unit=self.unit, **trace, exc=exc)
        if r.isError():
            raise ModbusExc(exc, f"{self.name} {self.text} unit {self.unit}: {what}")
        return r

    def read(self, addr: int, n: int) -> list[int]:
        r = self._call(f"read of {n} at {addr}",
                       lambda: self.client.read_holding_registers(addr, count=n,
                                                                  device_id=self.unit),
                       {"fc": 3, "ra": addr, "rq": n})
        return list(r.registers)

    def write(self, addr: int, values) -> None:
        values = list(values)
        self._call(f"write of {len(values)} at {addr}",
                   lambda: self.client.write_registers(addr, values, device_id=self.unit),
                   {"fc": 16, "wa": addr, "wq": len(values), "w0": values[0]})


def close_serial():
    for c in _SERIAL.values():
        c.close()
    _SERIAL.clear()
