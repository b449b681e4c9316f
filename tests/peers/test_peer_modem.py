"""The peer's transport seam (peers/mippeer/modem.py): over a function (Modem.in_process, what the
co-simulation kernel uses) the peer makes byte for byte the requests it makes over Modbus TCP,
reads the same answers, and reports a missing or refused answer as one ModemError line; and
cli.Loop, the command's round (read, step, write, events), runs on it."""
import socket
import struct
import threading

import pytest

from mippeer.cli import Loop, logger_records, received
from mippeer.modem import MDP810, TRM810, Modem, ModemError
from mippeer.peer import Peer


def answer(adu, regs=None):
    """A modem's answer to one request ADU: FC3 -> `regs` (zeros by default), FC16 -> the echo."""
    tid, _, _, unit, fc = struct.unpack(">HHHBB", adu[:8])
    if fc == 3:
        _, count = struct.unpack(">HH", adu[8:12])
        values = (list(regs or []) + [0] * count)[:count]
        pdu = bytes([3, 2 * count]) + struct.pack(f">{count}H", *values)
    else:
        pdu = adu[7:12]
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


class TcpModem:
    """A Modbus TCP server on 127.0.0.1 answering with answer(), keeping every request."""

    def __init__(self):
        self.requests = []
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.port = self.srv.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        conn, _ = self.srv.accept()
        with conn:
            buf = b""
            while True:
                data = conn.recv(4096)
                if not data:
                    return
                buf += data
                while len(buf) >= 6 and len(buf) >= 6 + struct.unpack(">H", buf[4:6])[0]:
                    n = 6 + struct.unpack(">H", buf[4:6])[0]
                    adu, buf = buf[:n], buf[n:]
                    self.requests.append(adu)
                    conn.sendall(answer(adu))

    def close(self):
        self.srv.close()


def _talk(modem):
    modem.connect()
    got = modem.read()
    modem.write([1, 2, 3])
    modem.write([0xFFFF] + [7] * 20)
    got2 = modem.read()
    modem.close()
    return got, got2


@pytest.mark.parametrize("device, unit", [("trm", 1), ("mdp", 3)])
def test_in_process_requests_are_the_tcp_requests_byte_for_byte(device, unit):
    tcp = TcpModem()
    try:
        over_tcp = _talk(Modem("127.0.0.1", tcp.port, device, unit))
    finally:
        tcp.close()
    adus = []
    over_fn = _talk(Modem.in_process(lambda adu: adus.append(adu) or answer(adu), device, unit))
    assert adus == tcp.requests and len(adus) == 4
    assert over_fn == over_tcp
    m = TRM810 if device == "trm" else MDP810
    # FC3 of 125 at the read-status register, FC16 at the first write register, the unit id
    assert struct.unpack(">BBHH", adus[0][6:12]) == (unit, 3, m.read_status, 125)
    assert struct.unpack(">BBHH", adus[1][6:12]) == (unit, 16, m.write_data, 3)


def test_in_process_read_returns_the_registers():
    modem = Modem.in_process(lambda adu: answer(adu, [1, 2, 0xFFFF, 9]), "trm")
    assert modem.read()[:5] == [1, 2, 0xFFFF, 9, 0]


@pytest.mark.parametrize("reply, why", [
    (lambda adu: None, "read at 2198"),                                   # no answer
    (lambda adu: adu[:7] + bytes([0x83, 2]), "read at 2198"),             # exception 2
])
def test_no_or_refused_answer_is_one_modem_error(reply, why):
    def fix_len(adu):          # the exception answer needs its MBAP length
        r = reply(adu)
        return None if r is None else r[:4] + struct.pack(">H", len(r) - 6) + r[6:]
    with pytest.raises(ModemError, match=why) as e:
        Modem.in_process(fix_len, "trm").read()
    assert "\n" not in str(e.value)


def test_loop_rounds_on_an_in_process_modem():
    """Two note peers, each a Loop on a function modem; the "radio" moves each written block
    into the other side's read area (the read status bit 0 until it is read)."""
    area = {"trm": None, "mdp": None}

    def modem(me, other):
        def transact(adu):
            fc = adu[7]
            if fc == 16:
                n = struct.unpack(">H", adu[10:12])[0]
                area[other] = list(struct.unpack(f">{n}H", adu[13:13 + 2 * n]))
                return answer(adu)
            block, area[me] = area[me], None
            return answer(adu, [1, len(block)] + block if block else [0, 0])
        return Modem.in_process(transact, me)

    records = logger_records(4, 5, 11)
    out = Loop(Peer("outstation", records, retransmit_s=0.5), modem("trm", "mdp"))
    cen = Loop(Peer("central"), modem("mdp", "trm"))
    for k in range(100):
        out.round(k * 0.02)
        cen.round(k * 0.02 + 0.01)
        if out.peer.done:
            break
    assert received(cen.peer)["transfers"] == [records]
    assert cen.events == [("accepted", n) for n in (1, 2, 3, 0xFFFF)]
    assert out.seen("acknowledged", 0xFFFF) and not out.seen("acknowledged", 0)
