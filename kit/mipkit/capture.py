"""A capture of the Modbus/TCP traffic between the PLCs and the emulated modems, as a pcapng file
that Wireshark (and tshark) open with dist/wireshark/mipmb.lua (docs/wireshark.md).

The kit's network runs in virtual time without sockets: each request ADU goes from the PLC's
runtime to the emulator core in-process. With a capture on (Net(capture_s=...), the pytest
option --mip-capture, mip-kit --capture), every request and its response are kept (the last
MAX_EXCHANGES of them: our choice, about 40 MB at most) and a failure writes the `capture_s`
virtual seconds around its fault (the failure report's fault, as its sequence diagram; else
the last seconds) as TCP segments of one connection per PLC device (or peer) and modem, each
opened with a handshake at its first exchange in the file. Each modem has an
address of its own and Modbus's port 502, as on a site (so Wireshark's Modbus/TCP dissector
and mipmb.lua take the frames with their default preferences): the MDP-810 127.0.2.1, the
TRM-810 of station s 127.0.1.s; the PLCs (and the kit's peers) are 127.0.0.1. Our choice: the
kit has no sockets, these addresses are only names in the file. Timestamps are the network's
virtual time (nanosecond resolution) from 1970-01-01, the start of the run.

pcapng (the IETF draft "PCAP Next Generation Dump File Format", sections 4.1 Section Header
Block, 4.2 Interface Description Block, 4.3 Enhanced Packet Block) with one Ethernet interface;
gzip-compressed when the name ends in .gz (Wireshark reads such files as they are).
"""
from __future__ import annotations

import collections
import ctypes
import gzip
import struct
from pathlib import Path

MODBUS_PORT = 502
PLC_ADDRESS = bytes([127, 0, 0, 1])
CLIENT_PORT = 40000         # first client port: one per connection
MAX_EXCHANGES = 100_000     # kept in memory (our choice): a realistic radio's hour at one PLC
_SYN, _ACK, _PSH_ACK = 0x02, 0x10, 0x18


def modem_address(ep: int) -> bytes:
    """The address a modem has in the file: 127.0.2.1 the MDP-810 (ep 0), 127.0.1.s the TRM-810
    of station s."""
    return bytes([127, 0, 2, 1]) if ep == 0 else bytes([127, 0, 1, ep])


def describe_addresses() -> str:
    return "the MDP-810 127.0.2.1, the TRM-810 of station s 127.0.1.s, port 502; PLCs 127.0.0.1"


def _csum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    s = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while s >> 16:
        s = (s & 0xFFFF) + (s >> 16)
    return ~s & 0xFFFF


def tcp_frame(sport: int, dport: int, seq: int, ack: int, payload: bytes = b"",
              flags: int = _PSH_ACK, src: bytes = PLC_ADDRESS, dst: bytes = PLC_ADDRESS) -> bytes:
    """An Ethernet frame of one IPv4 TCP segment (the IP header's checksum right; the TCP
    checksum left 0, which Wireshark does not check by default)."""
    tcp = struct.pack("!HHIIBBHHH", sport, dport, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4,
                      flags, 65535, 0, 0) + payload
    ip = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(tcp), 0, 0x4000, 64, 6, 0,
                     src, dst)
    ip = ip[:10] + struct.pack("!H", _csum(ip)) + ip[12:]
    return b"\0" * 12 + b"\x08\x00" + ip + tcp


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def _block(btype: int, body: bytes) -> bytes:
    n = 12 + len(body)
    return struct.pack("<II", btype, n) + body + struct.pack("<I", n)


def pcapng(frames, comment: str = "") -> bytes:
    """The bytes of a pcapng file of Ethernet frames [(t_ns, frame)], nanosecond timestamps."""
    shb_opts = (_option(1, comment.encode()) if comment else b"") + _option(0, b"")
    out = [_block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1) + shb_opts),
           _block(1, struct.pack("<HHI", 1, 0, 0) + _option(9, bytes([9])) + _option(0, b""))]
    for t_ns, frame in frames:
        body = struct.pack("<IIIII", 0, t_ns >> 32, t_ns & 0xFFFFFFFF, len(frame), len(frame))
        out.append(_block(6, body + frame + b"\0" * (-len(frame) % 4)))
    return b"".join(out)


class ModbusCapture:
    """Request/response pairs, per connection; a file holds `seconds` virtual seconds."""

    def __init__(self, seconds: float, max_exchanges: int = MAX_EXCHANGES):
        self.window_ns = int(seconds * 1e9)
        self.exchanges = collections.deque(maxlen=max_exchanges)  # (t_ns, conn, ep, req, rsp)
        self.conns: dict = {}                    # a connection's key -> its number

    def record(self, t_ns: int, key, ep: int, request: bytes, response: bytes | None):
        conn = self.conns.setdefault(key, len(self.conns))
        self.exchanges.append((t_ns, conn, ep, bytes(request),
                               None if response is None else bytes(response)))

    def window(self, centre_ns=None):
        """(from, to) in virtual ns: `seconds` centred on centre_ns (near the start or the end
        of the run, the whole window on the run's side, as the failure's diagram), or the last
        `seconds` of the capture."""
        last = self.exchanges[-1][0] if self.exchanges else 0
        if centre_ns is None:
            return max(0, last - self.window_ns), last
        t_from = max(0, min(centre_ns - self.window_ns // 2, last - self.window_ns))
        return t_from, t_from + self.window_ns

    def frames(self, window=None):
        """[(t_ns, Ethernet frame)]: each connection's handshake, requests and responses, of
        the exchanges in window (from, to) (default: all kept)."""
        state = {}          # conn -> [client port, client seq, server seq]
        out = []
        lo, hi = window or (0, float("inf"))
        for t, conn, ep, req, rsp in self.exchanges:
            if not lo <= t <= hi:
                continue
            m, sp = modem_address(ep), MODBUS_PORT
            if conn not in state:
                c = [CLIENT_PORT + conn, 1000, 5000]
                out += [(t, tcp_frame(c[0], sp, c[1] - 1, 0, flags=_SYN, dst=m)),
                        (t, tcp_frame(sp, c[0], c[2] - 1, c[1], flags=_SYN | _ACK, src=m)),
                        (t, tcp_frame(c[0], sp, c[1], c[2], flags=_ACK, dst=m))]
                state[conn] = c
            c = state[conn]
            out.append((t, tcp_frame(c[0], sp, c[1], c[2], req, dst=m)))
            c[1] += len(req)
            if rsp is not None:
                out.append((t, tcp_frame(sp, c[0], c[2], c[1], rsp, src=m)))
                c[2] += len(rsp)
        return out

    def save(self, path: Path, comment: str = "", window=None) -> Path:
        """Writes the pcapng file of window (from, to) (gzip-compressed for a name ending in
        .gz); returns path."""
        data = pcapng(self.frames(window), comment)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix == ".gz":
            data = gzip.compress(data, mtime=0)
        path.write_bytes(data)
        return path


def wire_device(net, kit_plc, plc, device: str, ep: int):
    """The modem device of a user's PLC, wired to the emulator core as mipcosim_connect_inproc
    would, through Python so that each exchange is recorded (net.capture). Kept on kit_plc
    (the runtime holds the callback)."""
    from mipcosim.pydevice import PyDevice
    rsp = ctypes.create_string_buffer(512)

    def handle(adu):
        n = net.kernel.request(ep, adu, rsp)
        out = rsp.raw[:n] if n >= 0 else None        # no answer: the runtime sees a timeout
        net.capture.record(net.now, (kit_plc.name, device), ep, adu, out)
        return out

    kit_plc.capture_devices[device] = PyDevice(plc, device, handle)


def recording(net, name: str, ep: int, transact):
    """A peer's transact(adu) -> response, recorded in net.capture."""
    def run(adu):
        out = transact(adu)
        net.capture.record(net.now, (name, "modem"), ep, adu, out)
        return out
    return run


def dissector() -> Path:
    """mipmb.lua: in the installed kit beside this module, else the checkout's."""
    here = Path(__file__).resolve()
    packaged = here.with_name("mipmb.lua")
    return packaged if packaged.is_file() else here.parents[2] / "dist" / "wireshark" / "mipmb.lua"


def save_for_report(net, outdir: Path, message: str = "", t_hint=None,
                    name: str = "modbus.pcapng.gz"):
    """A failed test's capture, centred on the failure report's fault (report.find_fault, from
    the failure's message): (section title, text, JUnit property) after writing outdir/name."""
    cap = net.capture
    centre = None
    if not net.kernel.closed:
        try:
            from .report import find_fault
            centre = find_fault(net, message, t_hint).t
        except Exception:  # noqa: BLE001 - without a fault, the last seconds
            centre = None
    lo, hi = cap.window(centre)
    what = (f"{lo / 1e9:.3f} s .. {hi / 1e9:.3f} s of virtual time, around the fault at "
            f"{centre / 1e9:.3f} s" if centre is not None else
            f"the last {cap.window_ns / 1e9:g} virtual seconds, {lo / 1e9:.3f} s .. {hi / 1e9:.3f} s")
    n = sum(1 for e in cap.exchanges if lo <= e[0] <= hi)
    path = cap.save(Path(outdir) / name, window=(lo, hi),
                    comment=f"mip-logger kit: Modbus/TCP of the PLCs and peers with the emulated "
                            f"modems, {what}; {describe_addresses()}")
    text = (f"{path} ({n} exchanges, {path.stat().st_size} bytes, {what}; "
            f"{describe_addresses()}): "
            f"wireshark -X lua_script:{dissector()} {path} (docs/wireshark.md)")
    return "Modbus capture", text, ("mip_capture", str(path))
