"""What stands on the network's stations: a user's soft-PLC (KitPlc) and a note-following peer
(KitPeer)."""
from __future__ import annotations

import ctypes

from mipcosim import sim as S
from plcharness import Plc

from . import capture, delivery
from .base import MS, RESPONSE_MAX, SCAN_FN, SEC, KitError, _warn
from .program import _LOCATED, _declared, _mapped, _ranges, _retain_period


class KitPlc:
    """A user's program on the network: read and write variables and located addresses by
    name (plcharness's names: "MAIN.x", "%QW100"); survives restarts (always the live instance)."""

    def __init__(self, net, name, result, config, at, retain_period_ms):
        self.net, self.name, self.result, self.config, self.at = net, name, result, config, at
        # the snapshot period: the test's, else the config's [retain] period (what plcrt does
        # with it), else 1 s; a test's that differs from the config's is said in one line
        conf = _retain_period(config) if config.suffix != ".cfg" else None
        if retain_period_ms is None:
            self.retain_period_ns = conf[2] if conf and conf[2] else 1000 * MS
        else:
            self.retain_period_ns = int(retain_period_ms * MS)
            if conf and conf[2] is not None and conf[2] != self.retain_period_ns:
                _warn(f"{config}:{conf[0]}: [retain] period = {conf[1]} is not what the kit uses "
                      f"for {name}: it takes snapshots every retain_period_ms = {retain_period_ms:g}")
        self._addresses = None
        self.plc = None
        self.pid = None
        self.restarts = []      # (virtual ns, mode, RETAIN restored)
        self._taps = None       # the delivery taps of the program's receivers (delivery.py)
        self._ends = {}         # device -> connect(KitPlc): a relay or UNICOS stand-in (ends.py)
        self.capture_devices = {}   # device -> its recording transport (capture.py)

    def _start(self, snapshot=None):
        net = self.net
        from .ends import slave_config
        plc = Plc(self.result, net.workdir, config=slave_config(self.config, net.workdir))
        plc.retain_in_memory(self.retain_period_ns)
        if snapshot is not None:
            plc.retain_load(snapshot)
        if self.pid is None:
            self.pid = net.kernel.add_plc(plc, name=self.name)
        else:
            net.kernel.replace(self.pid, plc, name=self.name)
        old, self.plc = self.plc, plc
        if old is not None:
            old.close()
        ep = 0 if self.at == "mdp" else int(self.at)
        for i in range(plc.library.plcrt_device_count(plc.handle)):
            dev = plc.library.plcrt_device_name(plc.handle, i)
            if dev.decode() in self._ends:
                self._ends[dev.decode()](self)      # the relay or control system (ends.py)
            elif net.capture is not None:
                capture.wire_device(net, self, plc, dev.decode(), ep)
            else:
                net.kernel.connect(self.pid, plc, dev, ep)
        if self._taps is None:
            self._taps = delivery.Taps(net, self.pid)
        self._taps.bind(plc, restored=snapshot is not None)

    def _receiver(self, receiver):
        self.net._drain()
        found = self._taps.by_path
        if receiver is None:
            if len(found) != 1:
                raise KitError(f"{self.name}: the program has {len(found)} MIP_Receiver "
                               f"instances ({', '.join(found) or 'none'}): name one")
            return next(iter(found.values()))
        want = receiver.strip().upper()
        hits = [r for p, r in found.items() if p == want or p.endswith("." + want)]
        if len(hits) != 1:
            raise KitError(f"{self.name}: {receiver}: "
                           f"{'no' if not hits else 'more than one'} MIP_Receiver of that name; "
                           f"the program has {', '.join(found) or 'none'}")
        return hits[0]

    @property
    def receivers(self):
        """Paths of the program's MIP_Receiver instances (a MIP_Link's receiving side is its
        inner RCV), found by their outputs."""
        return list(self._taps.by_path)

    def delivered(self, receiver=None):
        """The payloads a MIP_Receiver of the program delivered (xRecordValid), in order, like
        a peer's records: the tap for the integrator's own central, no glue in the program.
        receiver: its path or the end of it ("RCV1"); not needed with one receiver. A record
        without data (an empty 16#FFFF) is not delivered (st_lib/PROTOCOL.md P15); a warm
        restart forgets what the rolled-back instance delivered after its snapshot."""
        return list(self._receiver(receiver).records)

    def transfers_received(self, receiver=None):
        """Transfers that receiver completed (xTransferEnd)."""
        return self._receiver(receiver).transfers

    def _check_located(self, name):
        """A located address the program does not declare (nor the config map) reads 0 and
        writes nowhere: a one-line KitError instead."""
        if not isinstance(name, str) or not name.lstrip().startswith("%"):
            return
        if self._addresses is None:
            declared = _declared(self.result)
            openplc = self.config.suffix == ".cfg"
            self._addresses = (declared, set() if openplc else _mapped(self.config), openplc)
        declared, mapped, openplc = self._addresses
        addr = name.strip().upper()
        if addr in declared or addr in mapped or (openplc and not addr.startswith("%M")):
            return
        m = _LOCATED.fullmatch(addr)
        if m is None:
            return               # the harness says what is wrong with it
        same = sorted((a for a in declared if a[:3] == addr[:3] and "." not in a),
                      key=lambda a: int(a[3:]))
        have = f" (it declares {_ranges(same)})" if same else ""
        raise KitError(f"{self.name}: {name}: the program does not declare {addr}{have}: "
                       "reading it gives 0, writing it reaches nothing")

    def __getitem__(self, name):
        self._check_located(name)
        try:
            return self.plc[name]
        except Exception as e:  # noqa: BLE001 - the harness's own one-line message
            raise KitError(f"{self.name}: {name}: {e}") from None

    def __setitem__(self, name, value):
        self._check_located(name)
        try:
            self.plc[name] = value
        except Exception as e:  # noqa: BLE001
            raise KitError(f"{self.name}: {name}: {e}") from None

    def restart(self, mode="cold", down_s=0.5):
        """cold: a fresh instance (all state lost, RETAIN too); warm: the RETAIN variables of a
        snapshot taken at the stop (plcrt's SIGTERM); kill9: those of the last periodic
        snapshot (plcrt's kill -9: whatever changed since then is lost)."""
        if mode not in ("cold", "warm", "kill9"):
            raise KitError(f"{self.name}: restart mode {mode!r}: use cold, warm or kill9")
        snap = None
        if mode == "warm" and self.plc.retain_count():
            snap = self.plc.retain_save()
        elif mode == "kill9":
            snap = self.plc.retain_last()
        net = self.net
        net._drain()            # what the taps logged of the old instance
        net.kernel.replace(self.pid)
        # (when, mode, whether RETAIN was restored: not without RETAIN variables, nor before
        # the first snapshot; then it is cold)
        self.restarts.append((net.now, mode, snap is not None))
        net.run_for(down_s)
        self._start(snap)


class KitPeer:
    """mippeer's note-following Peer on a modem of the network (stands in for the other side)."""

    def __init__(self, net, name, at, role, records, lenient, layout, drive, period_ms,
                 retransmit_s, request_s, static_registers, unit=1):
        from mippeer.cli import Loop
        from mippeer.modem import Modem
        from mippeer.peer import Peer
        self.net, self.name, self.at = net, name, at
        ep = 0 if at == "mdp" else int(at)
        unit = unit if at == "mdp" else 1
        kernel = net.kernel
        rsp = ctypes.create_string_buffer(RESPONSE_MAX)

        def transact(adu):
            n = kernel.request(ep, adu, rsp)
            if n < 0:
                raise S.CosimError(kernel.errmsg())
            return rsp.raw[:n]

        try:
            peer = Peer(role, records, layout=layout, drive=drive, lenient=lenient,
                        retransmit_s=retransmit_s, request_s=request_s,
                        static_registers=static_registers)
        except ValueError as e:
            raise KitError(f"peer {name}: {e}") from None
        if net.capture is not None:
            transact = capture.recording(net, name, ep, transact)
        modem = Modem.in_process(transact, "mdp" if at == "mdp" else "trm", unit=unit)
        modem.connect()
        self.peer = peer
        self.loop = Loop(peer, modem)
        self.error = None
        self._t0 = net.now
        self._scan = SCAN_FN(self._round)
        self.pid = net.kernel.add_scan(self._scan, int(period_ms * MS))

    def _round(self, _rt, _n):
        try:
            self.loop.round((self.net.now - self._t0) / SEC)
            return 0
        except BaseException as e:  # noqa: BLE001 - handed back through the C loop
            self.error = e
            return -1

    @property
    def records(self):
        """Payloads of every record with data the peer accepted, in order (all transfers). An
        empty record (the 16#FFFF a sender writes after a last chunk that came without
        xChunkLast) ends its transfer but is no record: as MIP_Receiver, which does not deliver
        it (st_lib/PROTOCOL.md P15)."""
        r = self.peer.receiver
        if r is None:
            return []
        return [p for t in r.transfers for p in t if p] + [p for p in r.current if p]

    @property
    def transfers(self):
        r = self.peer.receiver
        return len(r.transfers) if r else 0

    @property
    def done(self):
        return self.peer.done
