"""Wrong settings produced on purpose, for mip-probe's tests (docs/commissioning.md, "Symptoms
of each wrong setting"): a modem set up wrong in one way, in front of one of the emulator's
endpoints, over Modbus TCP (FaultProxy) or Modbus RTU (FaultLine); and PLC clients that write
while the probe runs.

The wrong setting itself is `Faults`, on Modbus PDUs only; the two fronts differ in framing
alone (MBAP header, or unit id + CRC on a serial line):

- `one_based`: the modem counts its register addresses from 1 (the note's register N is at N-1).
- `static=N`: a TRM in static mode with N registers in front of an emulator in dynamic mode
  (the emulator has one mode for its whole network): the write count reads N, writes go into a
  148-register write area anywhere (FC6 too), a change of its first N registers sends those N
  (note §1.1.1) as one block through the emulator.
- `sticky_bit4`: bit 4 of the read status never clears (a modem that never reports the
  confirmation).
"""
import os
import select
import socket
import struct
import threading
import time
import tty

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.framer import FramerType

from miptest.emu import recv_exact
from miptest.rtu import crc16, frame
from mipprobe.regmap import TRM810 as T


class Faults:
    """One wrong setting, on Modbus PDUs: `handle(pdu, forward)` gives the answer's PDU, or None
    for silence; forward(pdu) asks the emulator behind (its answer's PDU, or None: silent)."""

    def __init__(self, one_based=False, static=None, sticky_bit4=False):
        self.one_based, self.static, self.sticky = one_based, static, sticky_bit4
        self.shadow = [0] * T.capacity
        self.lock = threading.Lock()       # one request at a time, as on a modem

    def handle(self, pdu, forward):
        with self.lock:
            return self._handle(pdu, forward)

    def _handle(self, pdu, forward):
        fc = pdu[0]
        if self.one_based and fc in (3, 4, 6, 16):
            (addr,) = struct.unpack(">H", pdu[1:3])
            pdu = pdu[:1] + struct.pack(">H", addr + 1) + pdu[3:]
        if self.static and fc in (3, 6, 16):
            local = self._static(forward, fc, pdu)
            if local is not None:
                return local
        rsp = forward(pdu)
        if rsp and self.sticky and fc == 3 and rsp[0] == 3:
            addr, n = struct.unpack(">HH", pdu[1:5])
            if addr <= T.read_status < addr + n:
                k = 2 + 2 * (T.read_status - addr)
                (v,) = struct.unpack(">H", rsp[k:k + 2])
                rsp = rsp[:k] + struct.pack(">H", v | 0x10) + rsp[k + 2:]
        return rsp

    def _static(self, forward, fc, pdu):
        n = self.static
        addr, q = struct.unpack(">HH", pdu[1:5])
        if fc == 3:
            if not (T.write_count <= addr and addr + q <= T.write_data + T.capacity):
                return None
            regs = [n if a == T.write_count else self.shadow[a - T.write_data]
                    for a in range(addr, addr + q)]
            return struct.pack(">BB", 3, 2 * q) + b"".join(struct.pack(">H", r) for r in regs)
        values = [q] if fc == 6 else list(struct.unpack(f">{q}H", pdu[6:6 + 2 * q]))
        if not (T.write_data <= addr and addr + len(values) <= T.write_data + T.capacity):
            return None
        before = self.shadow[:n]
        self.shadow[addr - T.write_data:addr - T.write_data + len(values)] = values
        if self.shadow[:n] != before:
            body = self.shadow[:n]
            rsp = forward(struct.pack(">BHHB", 16, T.write_data, n, 2 * n)
                          + b"".join(struct.pack(">H", r) for r in body))
            if rsp is None or rsp[0] & 0x80:
                return rsp
        return pdu[:5]


class FaultProxy:
    """A Modbus TCP endpoint in front of the emulator's port `upstream_port`, wrong as `Faults`."""

    def __init__(self, upstream_port, **faults):
        self.up_port = upstream_port
        self.faults = Faults(**faults)
        self.srv = socket.socket()
        self.srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(16)
        self.port = self.srv.getsockname()[1]
        self.done = False
        threading.Thread(target=self._accept, daemon=True).start()

    def close(self):
        self.done = True
        self.srv.close()

    def _accept(self):
        while not self.done:
            try:
                c, _ = self.srv.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(c,), daemon=True).start()

    def _serve(self, c):
        up = socket.create_connection(("127.0.0.1", self.up_port), timeout=10)
        try:
            while True:
                tid, _, length, unit = struct.unpack(">HHHB", recv_exact(c, 7))
                pdu = recv_exact(c, length - 1)

                def forward(p):
                    up.sendall(struct.pack(">HHHB", tid, 0, len(p) + 1, unit) + p)
                    _, _, n, _ = struct.unpack(">HHHB", recv_exact(up, 7))
                    return recv_exact(up, n - 1)
                rsp = self.faults.handle(pdu, forward)
                c.sendall(struct.pack(">HHHB", tid, 0, len(rsp) + 1, unit) + rsp)
        except (ConnectionError, OSError):
            pass
        finally:
            c.close()
            up.close()


def _request_len(b):
    """bytes of an RTU request frame from its start: None while unknown, -1 for a function
    code the tests do not send (the frame then ends with the line's silence)"""
    if len(b) < 2:
        return None
    fc = b[1]
    if fc in (1, 2, 3, 4, 5, 6):
        return 8
    if fc in (15, 16):
        return 9 + b[6] if len(b) >= 7 else None
    if fc == 23:
        return 13 + b[10] if len(b) >= 11 else None
    return -1


def _answer_len(b):
    if len(b) < 2:
        return None
    fc = b[1]
    if fc & 0x80:
        return 5
    if fc in (1, 2, 3, 4, 23):
        return 5 + b[2] if len(b) >= 3 else None
    return 8


def _read_frame(fd, length, first_timeout, quiet=0.05):
    """one frame from fd: its bytes once `length` says it is whole, or what came before the
    line was quiet for `quiet` s; b'' if nothing came within first_timeout"""
    out, wait = b"", first_timeout
    while True:
        n = length(out)
        if n is not None and 0 < n <= len(out):
            return out
        r, _, _ = select.select([fd], [], [], wait)
        if not r:
            return out
        try:
            out += os.read(fd, 512)
        except OSError:
            return out
        wait = quiet


class FaultLine:
    """A Modbus RTU front for the emulator's serial line `upstream` (its pty), wrong as `Faults`:
    each of `links` becomes a pty of its own (a client's serial port: the probe's, a PLC's) whose
    requests go over the one line behind, one at a time. A unit id nobody on the line has gets
    silence, as from the emulator (its silence ends after `silence` s: longer than an answer
    of the emulator takes on a loaded machine, shorter than what a client waits for one)."""

    def __init__(self, upstream, links, silence=0.9, **faults):
        self.faults = Faults(**faults)
        self.silence = silence
        self.up = os.open(str(upstream), os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.up)
        self.done = False
        self.ptys, self.links, self.threads = [], [str(p) for p in links], []
        for link in self.links:
            master, slave = os.openpty()    # the slave stays open: the client may close its end
            tty.setraw(master)
            tty.setraw(slave)
            os.symlink(os.ttyname(slave), link)
            self.ptys += [master, slave]
            t = threading.Thread(target=self._serve, args=(master,), daemon=True)
            t.start()
            self.threads.append(t)

    def close(self):
        self.done = True
        for t in self.threads:
            t.join(timeout=5)
        for link in self.links:
            os.unlink(link)
        for fd in self.ptys + [self.up]:
            os.close(fd)

    def _forward(self, unit, pdu):
        while select.select([self.up], [], [], 0)[0]:      # a late answer of a silence before
            os.read(self.up, 512)
        os.write(self.up, frame(unit, pdu))
        rsp = _read_frame(self.up, _answer_len, self.silence)
        if len(rsp) < 4 or crc16(rsp[:-2]) != rsp[-2] | rsp[-1] << 8:
            return None
        return rsp[1:-2]

    def _serve(self, fd):
        while not self.done:
            if not select.select([fd], [], [], 0.1)[0]:
                continue
            req = _read_frame(fd, _request_len, 0)
            if len(req) < 4 or crc16(req[:-2]) != req[-2] | req[-1] << 8 or req[0] == 0:
                continue                    # a broken frame or a broadcast: silence
            unit = req[0]
            rsp = self.faults.handle(req[1:-2], lambda p: self._forward(unit, p))
            if rsp is not None:
                os.write(fd, frame(unit, rsp))


class WritingPlc:
    """A PLC's client writing records to a TRM while the probe runs: whole blocks (FC16, one
    request) or split into single registers (FC6, one a PLC cycle of `cycle` s). `at`: the
    TRM's Modbus TCP port, or a serial device (Modbus RTU, 115200 baud 8N1, unit id `unit`)."""

    def __init__(self, at, split=False, cycle=0.03, registers=8, unit=1):
        if isinstance(at, int):
            self.c = ModbusTcpClient("127.0.0.1", port=at, timeout=2, retries=0)
        else:
            self.c = ModbusSerialClient(str(at), framer=FramerType.RTU, baudrate=115200,
                                        timeout=2, retries=0)
        assert self.c.connect()
        self.unit = unit
        self.split, self.cycle, self.n = split, cycle, registers
        self.done = False
        self.t = threading.Thread(target=self._run, daemon=True)
        self.t.start()

    def _run(self):
        rec = 0
        while not self.done:
            rec = rec % 65534 + 1
            block = [rec] + [(rec * 7 + j) & 0xFFFF for j in range(1, self.n)]
            if self.split:
                for j, v in enumerate(block):
                    if self.done:
                        return
                    self.c.write_register(T.write_data + j, v, device_id=self.unit)
                    time.sleep(self.cycle)
            else:
                self.c.write_registers(T.write_data, block, device_id=self.unit)
                time.sleep(self.cycle * self.n)

    def stop(self):
        self.done = True
        self.t.join(timeout=5)
        self.c.close()
