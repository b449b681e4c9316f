"""The two ends of the chain as devices of the user's PLCs (issue 35, docs/chain.md): the
SIPROTEC relay an outstation program reads (the emulator's C relay inside the kernel,
cosim/mipcosim/relay.py) and the WinCC OA UNICOS driver a central program writes to
(peers/mippeer/unicos.py through cosim/mipcosim/pydevice.py), single or a redundant pair,
taken down and brought back at given virtual times. Both replace the modem a device of the
PLC's config would otherwise talk to, and follow the PLC through its restarts.
"""
from __future__ import annotations

import collections
import ctypes
import hashlib
import socket
from pathlib import Path

from .base import MS, SCAN_FN, SEC, KitError


def _device_of(kp, device):
    """The device must be in the PLC's config, and not yet given to another stand-in."""
    lib, h = kp.plc.library, kp.plc.handle
    names = [lib.plcrt_device_name(h, i).decode() for i in range(lib.plcrt_device_count(h))]
    if device not in names:
        raise KitError(f"{kp.name}: device {device!r} is not in {kp.config} (it has "
                       f"{', '.join(names) or 'no devices'})")
    if device in kp._ends:
        raise KitError(f"{kp.name}: device {device!r} is given to a stand-in already")
    if kp.net.now > 0:
        # plcrt takes a device's transport only before the PLC's first scan
        raise KitError(f"{kp.name}: device {device!r}: give the relay / control system before "
                       "the network runs (at virtual time 0)")
    return device


def _times(pairs, what):
    """[(from_s, to_s), ...] of a driver's down times, checked."""
    out = []
    for p in pairs or ():
        if (not isinstance(p, (list, tuple)) or len(p) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in p)
                or not 0 <= p[0] < p[1]):
            raise KitError(f"{what} = {p!r}: a pair [from_s, to_s] of virtual seconds, "
                           "0 <= from_s < to_s")
        out.append((int(p[0] * SEC), int(p[1] * SEC)))
    return out


class KitRelay:
    """A SIPROTEC relay (the emulator's event recorder, docs/chain.md "The relay") that device
    `device` of PLC `kp` reads. events: scripted (t_s, [type/bit, address, cause/type, value]);
    rate (events/s) and burst (n, every_s): generated; base, capacity, overflow, seq_bits,
    bad_ack, origin_ms: as `mip-emulator --relay`."""

    def __init__(self, net, name, kp, device, events=(), **kw):
        from mipcosim.relay import Relay
        from mipcosim.sim import CosimError
        self.net, self.name, self.plc, self.device = net, name, kp, _device_of(kp, device)
        self.origin_ms = kw.get("origin_ms", 0)
        self.scripted = []          # (t_ns, [4 words]) in the order given
        try:
            self.relay = Relay(kernel=net.kernel, **kw)
        except (CosimError, TypeError, ValueError) as e:
            raise KitError(f"relay {name}: {e}") from None
        for ev in events:
            self.add(*ev)
        kp._ends[device] = self._connect
        self._connect(kp)

    def _connect(self, kp):
        from mipcosim.sim import CosimError
        try:
            self.relay.connect(kp.pid, kp.plc, self.device)
        except CosimError as e:
            raise KitError(f"relay {self.name}: {e}") from None

    def add(self, t_s, words):
        """One more scripted event at t_s virtual seconds (not in the past)."""
        if (not isinstance(words, (list, tuple)) or len(words) != 4
                or not all(isinstance(w, int) and 0 <= w <= 0xFFFF for w in words)):
            raise KitError(f"relay {self.name}: event {words!r}: four words [type/bit, address, "
                           "cause/type, value], each 0..65535")
        t_ns = int(round(t_s * SEC))
        if t_ns < self.net.now:
            raise KitError(f"relay {self.name}: event at {t_s:g} s: virtual time is at "
                           f"{self.net.now / SEC:g} s already")
        self.relay.add(t_s, list(words))
        self.scripted.append((t_ns, list(words)))

    def expected(self):
        """The scripted events as the relay records them: 8 words each (type/bit, address,
        cause/type, value, the time stamp in ms since 1970 in 4 words, most significant
        first: origin_ms + the event's virtual ms)."""
        out = []
        for t_ns, w in sorted(self.scripted, key=lambda x: x[0]):
            ms = self.origin_ms + t_ns // MS
            out.append(list(w) + [ms >> 48 & 0xFFFF, ms >> 32 & 0xFFFF, ms >> 16 & 0xFFFF, ms & 0xFFFF])
        return out

    def stats(self):
        """The relay's counters: entries (in the recorder now), generated, dropped (overflow),
        acknowledged, reset_cleared, bad_acks, seq, offered."""
        return self.relay.stats()

    def report(self):
        st = self.stats()
        return (f"relay {self.name}: {st['generated']} events ({len(self.scripted)} scripted), "
                f"{st['acknowledged']} acknowledged, {st['dropped']} dropped (overflow), "
                f"{st['entries']} still in the recorder")

    def missing(self, received):
        """The scripted events (8 words each) that `received` does not hold: received is a
        KitUnicos (its events, either driver), a list of 8-word entries, or of payloads whose
        words are 8-word entries back to back (a peer's records). Each expected event needs an
        entry of its own (a count, not a set); time stamps are compared too (a UNICOS event
        carries them in 10 ms)."""
        return missing(self.expected(), received)


def _as_entries(received):
    """(kind, list) of what reached the far side: ("unicos", event keys) or ("words", 8-word
    tuples)."""
    if isinstance(received, KitUnicos):
        return "unicos", received.unique()
    if isinstance(received, KitScada):
        received = received.unique()
    out = []
    for item in received:
        item = list(item)
        if len(item) % 8:
            raise KitError(f"a received item of {len(item)} words: relay entries are 8 words "
                           "each")
        out += [tuple(item[i:i + 8]) for i in range(0, len(item), 8)]
    return "words", out


def missing(expected, received):
    kind, got = _as_entries(received)
    if kind == "unicos":
        have = collections.Counter(got)
        keys = []
        for e in expected:
            ms = e[4] << 48 | e[5] << 32 | e[6] << 16 | e[7]
            keys.append([(e[1], e[0] << 16 | e[3], ms // 10), (e[1], e[3], ms // 10)])
    else:
        have = collections.Counter(got)
        keys = [[tuple(e)] for e in expected]
    out = []
    for e, ks in zip(expected, keys):
        k = next((k for k in ks if have[k] > 0), None)
        if k is None:
            out.append(list(e))
        else:
            have[k] -= 1
    return out


class KitUnicos:
    """WinCC OA's Modbus driver in UNICOS mode (peers/mippeer/unicos.py) as device `device`
    of PLC `kp`, and with device_b the redundant pair's second driver (B). marker: the
    reference number ([mod] addUnicosMarker); little_endian_register: [mod]
    littleEndianRegister; down / down_b: [(from_s, to_s), ...] of virtual time in which that
    driver does not answer (the PLC's client times out: plcrt status 1110)."""

    def __init__(self, net, name, kp, device, device_b=None, marker=0xFFFF,
                 little_endian_register=False, down=(), down_b=()):
        from mippeer.unicos import UnicosConfig, UnicosDriver
        self.net, self.name, self.plc = net, name, kp
        if not isinstance(marker, int) or not 0 <= marker <= 0xFFFF:
            raise KitError(f"unicos {name}: marker {marker!r}: a reference number 0..65535")
        cfg = UnicosConfig(marker=marker, little_endian_register=bool(little_endian_register))
        if device_b is None and down_b:
            raise KitError(f"unicos {name}: down_b without device_b (a single driver)")
        if device_b is not None and device_b == device:
            raise KitError(f"unicos {name}: device_b is the same device as device ({device!r})")
        self.devices = {"A": _device_of(kp, device)}
        if device_b is not None:
            self.devices["B"] = _device_of(kp, device_b)
        self.drivers = {d: UnicosDriver(d, cfg) for d in self.devices}
        self.down = {"A": _times(down, f"unicos {name}: down")}
        if device_b is not None:
            self.down["B"] = _times(down_b, f"unicos {name}: down_b")
        self.received_at = {d: [] for d in self.devices}    # virtual ns of each event, in order
        self._pydevs = {}
        for d, dev in self.devices.items():
            kp._ends[dev] = (lambda p, d=d: self._attach(p, d))
            self._attach(kp, d)

    def _handler(self, d):
        drv, down, net, at = self.drivers[d], self.down[d], self.net, self.received_at[d]

        def handle(adu):
            now = net.now
            if any(a <= now < b for a, b in down):
                return None                      # taken down: no answer at all
            n = len(drv.events)
            out = drv.handle(adu)
            at.extend([now] * (len(drv.events) - n))
            return out
        return handle

    def _attach(self, kp, d):
        from mipcosim.pydevice import PyDevice
        from mipcosim.sim import CosimError
        try:
            self._pydevs[d] = PyDevice(kp.plc, self.devices[d], self._handler(d))
        except CosimError as e:
            raise KitError(f"unicos {self.name}: {e}") from None

    def check(self):
        """Raise what a driver's handler raised (a bug of the stand-in, not of the program)."""
        for p in self._pydevs.values():
            p.check()

    def events(self, driver="A"):
        """The events driver A or B took, in order, each a dict: plc (the unit id), sub (17:
        32-bit, 18: 16-bit), offset, value, ts_10ms and utc (the event's time stamp), frame,
        duplicate (seen before by this driver), t_s (the virtual time it arrived)."""
        if driver not in self.drivers:
            raise KitError(f"unicos {self.name}: driver {driver!r}: have {', '.join(self.drivers)}")
        self.check()
        return [dict(e, t_s=t / SEC) for e, t in zip(self.drivers[driver].events,
                                                       self.received_at[driver])]

    def duplicates(self, driver="A"):
        """Events the driver took more than once (same PLC, subfunction, offset, value, time
        stamp): what WinCC OA would take as a new value each time."""
        return [e for e in self.events(driver) if e["duplicate"]]

    def unique(self):
        """(offset, value, ts_10ms) of every event either driver took, once each (a redundant
        pair's drivers both get every frame)."""
        seen, out = set(), []
        for d in self.drivers:
            for e in self.events(d):
                k = (e["plc"], e["sub"], e["offset"], e["value"], e["ts_10ms"])
                if k not in seen:
                    seen.add(k)
                    out.append((e["offset"], e["value"], e["ts_10ms"]))
        return out

    def report(self):
        """One line: events per driver, duplicates, refused frames, requests left unanswered."""
        parts = []
        for d, drv in self.drivers.items():
            pd = self._pydevs.get(d)
            parts.append(f"driver {d}: {len(drv.events)} events, {drv.duplicates} duplicates, "
                         f"{drv.refused} refused, {pd.unanswered if pd else 0} unanswered")
        return f"unicos {self.name}: " + "; ".join(parts)


def slave_config(config: Path, workdir: Path) -> Path:
    """The config the kit loads: a plcrt config with a [slave] section listens on a free port
    in the kit (the SCADA stand-in reaches it in process; port 502 needs root and two tests
    would share it): a copy with port = 0, every other line where it was (plcrt's messages keep
    their line numbers; a [slave] without a port key gets the line after its header). Other
    configs as they are."""
    from .program import _read_config
    cfg = _read_config(config)
    slave = cfg.section("slave") if cfg else None
    if slave is None:
        return config
    lines = config.read_text().split("\n")
    if "port" in slave.key_lines:
        lines[slave.key_lines["port"] - 1] = "port = 0"
    else:
        lines.insert(slave.line, "port = 0")
    out = Path(workdir) / "configs" / hashlib.sha1(str(config.resolve()).encode()).hexdigest()[:10]
    out.mkdir(parents=True, exist_ok=True)
    out = out / config.name
    out.write_text("\n".join(lines))
    return out


class KitScada:
    """The SCADA master of the pull way (peers/mippeer/scada.py's SoeMaster, written from the
    SOE handshake alone) polling the Modbus slave of PLC `kp` (its [slave] section; the
    program's MIP_SoeServer) every poll_ms, in process and in virtual time: a request is
    answered at once from the PLC's image of its last scan (a LAN without delay). base: the
    register of the event count (600 = 40601); reack: seconds before an unchanged offer is
    acknowledged again; down: [(from_s, to_s), ...] without polls (the SCADA stopped)."""

    def __init__(self, net, name, kp, base=600, poll_ms=100, reack=1.0, down=()):
        from mippeer.scada import Client, SoeMaster
        if kp.plc.slave_port <= 0:
            raise KitError(f"scada {name}: {kp.name}'s config {kp.config} has no [slave] "
                           "section: the SCADA polls the PLC's Modbus slave")
        if not isinstance(base, int) or not 0 <= base <= 65535 - 26:
            raise KitError(f"scada {name}: base {base!r}: a register 0..65509")
        if not isinstance(poll_ms, (int, float)) or poll_ms <= 0:
            raise KitError(f"scada {name}: poll_ms {poll_ms!r}: a period in ms, > 0")
        self.net, self.name, self.plc = net, name, kp
        self.down = _times(down, f"scada {name}: down")
        self.rows = []              # the entries taken, in order (dicts of mippeer.scada.entry)
        self.failures = 0           # polls that failed (no answer, connection gone)
        kit = self

        class InProcess(Client):
            """mippeer's client on one end of a socket pair whose other end the PLC's slave
            serves (plcrt_slave_add_client); a new pair after a failure (a restarted PLC)."""

            def _connect(self):
                if self.sock is None:
                    a, b = socket.socketpair()
                    lib = kit.plc.plc.library
                    lib.plcrt_slave_add_client.argtypes = [ctypes.c_void_p, ctypes.c_int]
                    if lib.plcrt_slave_add_client(kit.plc.plc.handle, b.detach()) != 0:
                        a.close()
                        raise ScadaError("the PLC's slave refused the connection")
                    a.settimeout(0.5)
                    self.sock = a

        from mippeer.scada import ScadaError

        def serve():
            lib = kit.plc.plc.library
            lib.plcrt_slave_poll.argtypes = [ctypes.c_void_p, ctypes.c_int]
            lib.plcrt_slave_poll(kit.plc.plc.handle, 0)

        self._client = InProcess("kit", 0, after_send=serve)

        def sink(entries):
            t = net.now / SEC
            for e in entries:
                e["t_s"] = t
                k = (e["type_bit"], e["address"], e["value"], e["ts_ms"])
                e["duplicate"] = k in self._seen
                self._seen.add(k)
            self.rows.extend(entries)

        self._seen = set()
        self.master = SoeMaster(self._client, base, sink, reack)
        self.error = None
        self._scan = SCAN_FN(self._poll)
        self.pid = net.kernel.add_scan(self._scan, int(poll_ms * MS))

    def _poll(self, _rt, _n):
        from mippeer.scada import ScadaError
        now = self.net.now
        if any(a <= now < b for a, b in self.down):
            self._client.close()
            return 0
        try:
            self.master.poll(now / SEC)
        except ScadaError:
            self.failures += 1          # read again at the next poll, as the master's CLI does
        except BaseException as e:  # noqa: BLE001 - handed back through the C loop
            self.error = e
            return -1
        return 0

    def check(self):
        if self.error is not None:
            e, self.error = self.error, None
            raise e

    def entries(self):
        """The entries taken, in order: type_bit, address, cause_type, value, ts_ms, regs (the
        8 registers), offer, seq, t_s (virtual time taken), duplicate (taken before)."""
        return list(self.rows)

    def duplicates(self):
        return [e for e in self.rows if e["duplicate"]]

    def unique(self):
        """The 8 registers of every entry taken, once each."""
        seen, out = set(), []
        for e in self.rows:
            k = tuple(e["regs"])
            if k not in seen:
                seen.add(k)
                out.append(list(k))
        return out

    def report(self):
        m = self.master
        return (f"scada {self.name}: {len(self.rows)} entries, {len(self.duplicates())} "
                f"duplicates, {m.acks} acknowledgements ({m.reacks} repeated, {m.refused} "
                f"refused), {self.failures} failed polls")
