"""A minimal Modbus RTU client on a pty (or any tty) for the tests: the frames are built by hand
(unit id, PDU, CRC-16 low byte first) so that broken ones can be sent too."""
import os
import select
import struct
import time
import tty


def crc16(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def frame(unit: int, pdu: bytes) -> bytes:
    body = bytes([unit]) + pdu
    c = crc16(body)
    return body + bytes([c & 0xFF, c >> 8])


def fc3(addr, count):
    return struct.pack(">BHH", 3, addr, count)


def fc16(addr, values):
    return struct.pack(">BHHB", 16, addr, len(values), 2 * len(values)) + b"".join(
        struct.pack(">H", v) for v in values)


def char_s(baud, frame_fmt="8N1"):
    bits = 1 + int(frame_fmt[0]) + (frame_fmt[1] != "N") + int(frame_fmt[2])
    return bits / baud


class RtuLine:
    def __init__(self, path):
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)

    def close(self):
        os.close(self.fd)

    def send(self, raw: bytes):
        os.write(self.fd, raw)

    def receive(self, first_timeout=1.0, quiet=0.05):
        """bytes until the line has been quiet for `quiet` s after the first byte; b'' if nothing
        came within first_timeout"""
        out = b""
        wait = first_timeout
        while True:
            r, _, _ = select.select([self.fd], [], [], wait)
            if not r:
                return out
            out += os.read(self.fd, 1024)
            wait = quiet

    def transact(self, unit, pdu, first_timeout=1.0):
        t0 = time.monotonic()
        self.send(frame(unit, pdu))
        rsp = self.receive(first_timeout)
        return rsp, time.monotonic() - t0


def check_frame(rsp: bytes):
    """unit id + PDU of a response whose CRC is right (AssertionError otherwise)"""
    assert len(rsp) >= 4, rsp
    assert crc16(rsp[:-2]) == rsp[-2] | rsp[-1] << 8, f"bad CRC in {rsp.hex()}"
    return rsp[0], rsp[1:-2]
