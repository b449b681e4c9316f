"""Wrong settings produced on purpose, for mip-probe's tests (docs/commissioning.md, "Symptoms
of each wrong setting"): a Modbus TCP endpoint in front of one of the emulator's that behaves as
a modem set up wrong in one way, and PLC clients that write while the probe runs.

- `one_based`: the modem counts its register addresses from 1 (the note's register N is at N-1).
- `static=N`: a TRM in static mode with N registers in front of an emulator in dynamic mode
  (the emulator has one mode for its whole network): the write count reads N, writes go into a
  148-register write area anywhere (FC6 too), a change of its first N registers sends those N
  (note §1.1.1) as one block through the emulator.
- `sticky_bit4`: bit 4 of the read status never clears (a modem that never reports the
  confirmation).
"""
import socket
import struct
import threading
import time

from pymodbus.client import ModbusTcpClient

from emu_support import recv_exact
from mipprobe.regmap import TRM810 as T


class FaultProxy:
    def __init__(self, upstream_port, one_based=False, static=None, sticky_bit4=False):
        self.up_port = upstream_port
        self.one_based, self.static, self.sticky = one_based, static, sticky_bit4
        self.shadow = [0] * 148
        self.lock = threading.Lock()
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
                head = recv_exact(c, 7)
                tid, proto, length, unit = struct.unpack(">HHHB", head)
                pdu = recv_exact(c, length - 1)
                with self.lock:
                    rsp = self._handle(up, tid, unit, pdu)
                c.sendall(struct.pack(">HHHB", tid, 0, len(rsp) + 1, unit) + rsp)
        except (ConnectionError, OSError):
            pass
        finally:
            c.close()
            up.close()

    def _forward(self, up, tid, unit, pdu):
        up.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
        _, _, length, _ = struct.unpack(">HHHB", recv_exact(up, 7))
        return recv_exact(up, length - 1)

    def _handle(self, up, tid, unit, pdu):
        fc = pdu[0]
        if self.one_based and fc in (3, 4, 6, 16):
            (addr,) = struct.unpack(">H", pdu[1:3])
            pdu = pdu[:1] + struct.pack(">H", addr + 1) + pdu[3:]
        if self.static and fc in (3, 6, 16):
            local = self._static(up, tid, unit, fc, pdu)
            if local is not None:
                return local
        rsp = self._forward(up, tid, unit, pdu)
        if self.sticky and fc == 3 and rsp[0] == 3:
            addr, n = struct.unpack(">HH", pdu[1:5])
            if addr <= T.read_status < addr + n:
                k = 2 + 2 * (T.read_status - addr)
                (v,) = struct.unpack(">H", rsp[k:k + 2])
                rsp = rsp[:k] + struct.pack(">H", v | 0x10) + rsp[k + 2:]
        return rsp

    def _static(self, up, tid, unit, fc, pdu):
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
            rsp = self._forward(up, tid, unit, struct.pack(">BHHB", 16, T.write_data, n, 2 * n)
                                + b"".join(struct.pack(">H", r) for r in body))
            if rsp[0] & 0x80:
                return rsp
        return pdu[:5]


class WritingPlc:
    """A PLC's client writing records to a TRM while the probe runs: whole blocks (FC16, one
    request) or split into single registers (FC6, one a PLC cycle of `cycle` s)."""

    def __init__(self, port, split=False, cycle=0.03, registers=8):
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
        assert self.c.connect()
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
                    self.c.write_register(T.write_data + j, v)
                    time.sleep(self.cycle)
            else:
                self.c.write_registers(T.write_data, block)
                time.sleep(self.cycle * self.n)

    def stop(self):
        self.done = True
        self.t.join(timeout=5)
        self.c.close()
