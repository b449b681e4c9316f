"""The stand-in tests' Modbus server: miptest.rt.ModbusServer (FC 3/4/6/16) with function 23
(write, then read, as the Modbus spec orders it) and a scripted exception reply, so that every
documented error of the vendor blocks can be reached."""
import struct
import time

from miptest.rt import ModbusServer


class ScriptedServer(ModbusServer):
    def __init__(self, size=3000):
        super().__init__(size=size)
        self.exception = 0          # answer every request with this exception code (0: none)
        self.delay = 0.0            # seconds before each reply (a slow line behind the server)
        self.malformed = False      # answer reads with a byte count that does not fit the request

    def _handle(self, pdu):
        if self.delay:
            time.sleep(self.delay)
        fc = pdu[0]
        with self.lock:
            if self.malformed and fc == 3:
                self.log.append((fc, "malformed"))
                return bytes([fc, 2]) + b"\x00\x01"
            if self.exception:
                self.log.append((fc, "exception", self.exception))
                return bytes([fc | 0x80, self.exception])
            if fc == 23:
                raddr, rcount, waddr, wcount, _n = struct.unpack(">HHHHB", pdu[1:10])
                self.log.append((23, raddr, rcount, waddr, wcount))
                if raddr + rcount > len(self.holding) or waddr + wcount > len(self.holding):
                    return bytes([fc | 0x80, 2])
                self.holding[waddr:waddr + wcount] = struct.unpack(f">{wcount}H",
                                                                   pdu[10:10 + 2 * wcount])
                return bytes([fc, 2 * rcount]) + struct.pack(f">{rcount}H",
                                                              *self.holding[raddr:raddr + rcount])
        return super()._handle(pdu)
