"""A live run of the docs' chain (docs/tools/chainsim.py) that the page drives."""
from __future__ import annotations

import ctypes
import random
from pathlib import Path

from mipcosim.sim import FATE_FN
from mipdocs.chainsim import Chain, ChainError, Side
from mipdocs.gen_traces import WORK, logger_data
from mipprobe.regmap import MDP810, TRM810

from .common import MS, ViewError, diagram, enum_name
from .presets import PRESETS
from .rows import History

FATE_OK, FATE_LOST = 0, 1            # mipemu.h: enum mipemu_fate
SLOT_LIMIT_MS = 10_000               # "one radio slot" gives up after this much virtual time
# The register windows (emulator/README.md "Register maps", from the application note's
# register tables): (title, endpoint, unit, first address, count). Endpoint 0 is the MDP-810
# (unit = station), 1 the TRM-810 of station 1 (mipemu.h).
WINDOWS = [
    (f"TRM-810 write ({TRM810.write_count}: count, {TRM810.write_data}..: record)", 1, 1,
     TRM810.write_count, 9),
    (f"TRM-810 read ({TRM810.read_status}: status, {TRM810.read_count}: count, "
     f"{TRM810.read_data}..: acknowledgement)", 1, 1, TRM810.read_status, 9),
    (f"MDP-810 read, station 1 ({MDP810.read_status}: status, {MDP810.read_count}: count, "
     f"{MDP810.read_data}..: record)", 0, 1, MDP810.read_status, 9),
    (f"MDP-810 write, station 1 ({MDP810.write_count}: count, {MDP810.write_data}..: "
     "acknowledgement)", 0, 1, MDP810.write_count, 9),
]
# what each register of a window is (offset from the window's first register): a short name
# under its address and a tooltip. The areas are the emulator's (emulator/README.md "Register
# maps", from the note's register tables); what the blocks put in them is st_lib/PROTOCOL.md's
# (the record counter and the acknowledgement in the first register of a block, the note's
# "Datensatzzähler" / "Bestätigungszähler"; acknowledgements 0 and 1 of our receiver carry the
# echo [ack, 16#4D50, check], P8).
_STATUS = ("status", "read status: bit 0 new data, bit 1 write data waiting, bit 4 write data "
                     "not yet confirmed by the link (emulator/README.md)")
_COUNT_RX = ("count", "number of registers received (the block's length)")
_COUNT_TX = ("count", "number of registers written (the block's length, set by the write)")
_RECORD = ("record", "record counter: 1, 2, ... 16#FFFF for the last record, 0 the reset "
                     "record (the note's Datensatzzähler)")
_ACK = ("ack", "acknowledgement counter: the last record the receiver accepted; 0 (start): "
               "nothing yet, 16#FFFF: the last record (the note's Bestätigungszähler)")
_MAGIC = ("echo", "16#4D50 ('MP'): the echo magic our MIP_Receiver writes with acknowledgements "
                  "0 and 1 (st_lib/PROTOCOL.md P8); with a 1-register acknowledgement (count 1) "
                  "it is left over from the last 3-register one")
_CHECK = ("check", "check value of the record acknowledged, with acknowledgements 0 and 1 "
                   "(st_lib/PROTOCOL.md P8); with a 1-register acknowledgement (count 1) it is "
                   "left over from the last 3-register one")
_DATA = ("data", "the record's data: the logger's registers")
_UNUSED = ("-", "not part of the block (an acknowledgement has 1 or 3 registers)")
REGISTERS = {
    TRM810.write_count: [_COUNT_TX, _RECORD] + [_DATA] * 7,
    TRM810.read_status: [_STATUS, _COUNT_RX, _ACK, _MAGIC, _CHECK] + [_UNUSED] * 4,
    MDP810.read_status: [_STATUS, _COUNT_RX, _RECORD] + [_DATA] * 6,
    MDP810.write_count: [_COUNT_TX, _ACK, _MAGIC, _CHECK] + [_UNUSED] * 5,
}


def shown(name, value):
    """A register as the note writes it: counters 16#FFFF, the echo magic in hex."""
    if name in ("record", "ack") and value == 0xFFFF:
        return "16#FFFF"
    if name == "echo" and value == 0x4D50:
        return "16#4D50"
    return str(value)


SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 50.0)   # virtual seconds per real second

# what the page shows of each block: (member, enum type or None)
SENDER_VIEW = [("eState", "E_MIP_SenderState"), ("eWaitReason", "E_MIP_WaitReason"),
               ("wRecord", None), ("udiRecords", None), ("udiRetransmissions", None),
               ("udiUnexpectedAcks", None), ("udiTransfers", None),
               ("eErrorId", "E_MIP_Error")]
RECEIVER_VIEW = [("eState", "E_MIP_ReceiverState"), ("eWaitReason", "E_MIP_WaitReason"),
                 ("wAck", None), ("udiRecords", None), ("udiDuplicates", None),
                 ("udiUnexpected", None), ("udiTransfers", None),
                 ("udiFailedTransfers", None), ("eErrorId", "E_MIP_Error")]

# the tooltips of the blocks' members (st_lib/core/MIP_Sender.st, MIP_Receiver.st)
VAR_TIPS = {
    "eState": "the block's state (E_MIP_SenderState / E_MIP_ReceiverState, st_lib/core/MIP_Types.st)",
    "eWaitReason": "what the block waits for (E_MIP_WaitReason)",
    "wRecord": "the record in flight: 1, 2, ... 16#FFFF the last",
    "wAck": "the last acknowledgement written: 0 (start), then the record accepted, 16#FFFF the last",
    "udiRecords": "records sent and acknowledged (sender) / accepted (receiver)",
    "udiRetransmissions": "records the block wrote again after tTimeout without an acknowledgement"
                          " (the modem's own repeats on the radio are not counted here)",
    "udiUnexpectedAcks": "acknowledgements that fit no record in flight (out of step, P11)",
    "udiTransfers": "transfers complete",
    "udiDuplicates": "records received again and discarded (a repeat after a lost confirmation)",
    "udiUnexpected": "records ignored: neither the next one nor a duplicate (P20)",
    "udiFailedTransfers": "transfers given up",
    "eErrorId": "the last error (E_MIP_Error)",
}


class Windows:
    """The register windows and which registers changed since the last look."""

    def __init__(self):
        self.last = {}

    def peek(self, lib, net):
        """The windows of the emulator core `net` (mipemu_net_peek: no side effects)."""
        vals = []
        for title, ep, unit, addr, n in WINDOWS:
            buf = (ctypes.c_uint16 * n)()
            lib.mipemu_net_peek(net, ep, unit, addr, n, buf)
            vals.append((title, addr, list(buf)))
        return self.show(vals)

    def show(self, values_by_title):
        out = []
        for title, start, values in values_by_title:
            old = self.last.get(title)
            changed = [i for i, v in enumerate(values) if old is not None and old[i] != v]
            self.last[title] = values
            names = REGISTERS[start]
            out.append({"title": title, "start": start, "values": values, "changed": changed,
                        "names": [n for n, _ in names], "tips": [tip for _, tip in names],
                        "shown": [shown(n, v) for (n, _), v in zip(names, values)]})
        return out


class Stepping:
    """Stepping a run by radio slot or by time, for any session with step(), `lines` (its
    trace so far) and `t_ns` (its virtual time)."""

    @property
    def t_ms(self):
        return self.t_ns // MS

    def step_slot(self):
        """Scan ticks up to and including the next radio telegram."""
        n = len(self.lines)
        end = self.t_ns + SLOT_LIMIT_MS * MS
        while self.t_ns < end:
            self.step()
            if any(d.get("ev") == "radio" for d in self.lines[n:]):
                return True
            n = len(self.lines)
        return False

    def advance(self, ms):
        """Scan ticks for ms of virtual time (a jump ahead, e.g. to a moment of an exercise)."""
        if not 0 < ms <= 600_000:
            raise ViewError("advance: ms must be 1..600000")
        end = self.t_ns + ms * MS
        while self.t_ns < end:
            self.step()

    def set_speed(self, s):
        if s not in SPEEDS:
            raise ViewError(f"speed {s}: one of {', '.join(f'{x:g}' for x in SPEEDS)}")
        self.speed = s


class Live(Stepping):
    """A run of the docs' chain the page drives: pause, step, speed, extra loss, lose the next
    record or acknowledgement, PLC restarts."""

    mode = "live"

    def __init__(self, preset="demo", workdir: Path | None = None):
        if preset not in PRESETS:
            raise ViewError(f"unknown preset {preset!r}: use one of {', '.join(PRESETS)}")
        self.preset_name = preset
        self.preset = p = PRESETS[preset]
        self.workdir = Path(workdir) if workdir else WORK
        payload = 122
        self.data = logger_data(p.records * payload, p.seed)
        self.o = Side("outstation", "sender", data=self.data, polled=p.polled,
                      timeout_ms=p.timeout_ms)
        self.c = Side("central", "receiver", polled=p.polled, timeout_ms=p.timeout_ms,
                      read_phase_ms=50)
        try:
            self.ch = Chain(self.workdir, self.o, self.c, loss_up=p.loss_up,
                            loss_down=p.loss_down, burst=p.burst, seed=p.seed)
        except ChainError as e:
            raise ViewError(str(e)) from None
        self.paused = False
        self.speed = 1.0
        # the view's own loss (our choice, on top of the preset's loss model, which the
        # emulator fixes at the start): telegrams that carry a block, from a seeded generator
        self.extra = {"up": 0.0, "down": 0.0}
        self.rng = random.Random(p.seed)
        self.lose_next = {"up": False, "down": False}     # a record / an acknowledgement
        self.scripted = p.lose_record                     # the preset's lost record, once
        self.lost_by_view = []                            # (t_ms, dir, first register)
        self.off = {}                                     # side name -> virtual ms it returns
        self.restarted = p.restart is None
        self.windows = Windows()
        self.history = History()
        self._fate = FATE_FN(self._on_fate)               # kept alive as long as the network
        self.ch.kernel.lib.mipemu_net_set_fate(self.ch.kernel.net, self._fate, None)

    # ---------------------------------------------------------------- the simulation
    def _on_fate(self, user, station, up, blk, n):
        d = "up" if up else "down"
        if up and n and self.scripted and blk[0] == self.scripted:
            self.scripted = 0
            return FATE_LOST
        if self.lose_next[d]:
            self.lose_next[d] = False
            self.lost_by_view.append((self.ch.t // MS, d, blk[0] if n else None))
            return FATE_LOST
        if self.extra[d] and self.rng.random() < self.extra[d]:
            self.lost_by_view.append((self.ch.t // MS, d, blk[0] if n else None))
            return FATE_LOST
        return FATE_OK

    @property
    def t_ns(self):
        return self.ch.t

    @property
    def lines(self):
        return self.ch.lines

    @property
    def tick(self):
        """One scan tick (ns): what the server's clock steps."""
        return self.ch.tick

    @property
    def done(self):
        return self.o.send_done and self.c.send_done and self.ch.t > 0 and not self.off

    def step(self):
        """One scan tick, with the preset's restart and the end of a power-off when due."""
        p = self.preset
        if not self.restarted and self.ch.t >= p.restart_at_ms * MS:
            self.ch.restart(self.o if p.restart == "outstation" else self.c)
            self.restarted = True
        self.ch.step()
        for name, back_ms in list(self.off.items()):
            if self.t_ms >= back_ms:           # on again: scanned from the next tick
                del self.off[name]
                self._power_on(name)

    def side(self, name):
        if name not in ("outstation", "central"):
            raise ViewError(f"unknown PLC {name!r}: outstation or central")
        return self.o if name == "outstation" else self.c

    def restart(self, name, kind="cold", outage_ms=1000):
        """cold: a fresh program instance now (all state lost, chainsim's restart). warm: the
        PLC is off for outage_ms (not scanned, its modem runs on) and resumes with all its
        memory, as a PLC whose whole state is durable (st_lib/PROTOCOL.md W3)."""
        side = self.side(name)
        if kind not in ("cold", "warm"):
            raise ViewError(f"restart kind {kind!r}: cold or warm")
        if side.plc is None:
            raise ViewError(f"the {name} PLC has not started yet (it starts at "
                            f"{side.read_phase_ms} ms)")
        if name in self.off:
            raise ViewError(f"the {name} PLC is off already (back at {self.off[name]} ms)")
        if kind == "cold":
            self.ch.restart(side)
        elif kind == "warm":
            if not 10 <= outage_ms <= 600_000:
                raise ViewError("outage_ms must be 10..600000")
            self.ch._emit(side._line(self.ch.t, "restart",
                                     f"PLC off for {outage_ms} ms (warm restart)", 0))
            self.ch.kernel.replace(self.ch.ids[name])
            self.off[name] = self.t_ms + outage_ms
        else:
            raise ViewError(f"restart kind {kind!r}: cold or warm")

    def _power_on(self, name):
        side = self.side(name)
        plc = side.plc
        self.ch._emit(side._line(self.ch.t, "restart", "PLC on again, its memory kept", 0))
        self.ch.kernel.replace(self.ch.ids[name], plc, self.ch.tick)
        # not wired again: the kernel keeps the PLC's connection across a replace (only its
        # taps and half-exchanged bytes go, cosim/src/mipcosim.c drop_plc_wiring) and the
        # instance keeps its transport (plcrt takes one only before its first scan)

    def set_loss(self, direction, p):
        if direction not in self.extra:
            raise ViewError(f"direction {direction!r}: up or down")
        if not 0.0 <= p <= 1.0:
            raise ViewError("loss must be 0..1")
        self.extra[direction] = p

    def lose(self, what):
        """Lose the next telegram that carries a record (uplink: the outstation's block) or an
        acknowledgement (downlink: the central's block)."""
        if what not in ("record", "ack"):
            raise ViewError(f"lose {what!r}: record or ack")
        self.lose_next["up" if what == "record" else "down"] = True

    # ---------------------------------------------------------------- what the page shows
    def _block(self, side):
        if side.plc is None:
            return {"side": side.name, "block": "-", "vars": []}
        view = SENDER_VIEW if side.role == "sender" else RECEIVER_VIEW
        out = []
        for member, enum in view:
            v = side.fbv(member)
            if enum:
                value = enum_name(enum, v)
            elif member in ("wRecord", "wAck"):
                value = "16#FFFF (last)" if v == 0xFFFF else (
                    "0 (start)" if v == 0 and member == "wAck" else v)
            else:
                value = v
            out.append({"name": member, "value": value, "tip": VAR_TIPS.get(member, "")})
        block = "MIP_Sender" if side.role == "sender" else "MIP_Receiver"
        return {"side": side.name, "block": block, "vars": out,
                "off": side.name in self.off}

    def _registers(self):
        return self.windows.peek(self.ch.kernel.lib, self.ch.kernel.net)

    def state(self):
        dg = diagram(self.history, self.ch.lines, f"{self.preset.title} (live)")
        st = self.ch.stats(1)
        return {
            "mode": self.mode, "preset": self.preset_name, "title": self.preset.title,
            "mipsim": self.preset.mipsim_args(), "t_ms": self.t_ms, "paused": self.paused,
            "speed": self.speed, "extra_loss": dict(self.extra), "lose_next": {
                "record": self.lose_next["up"], "ack": self.lose_next["down"]},
            "done": self.done, **dg,
            "registers": self._registers(), "blocks": [self._block(self.o), self._block(self.c)],
            "radio": {"polls": st["polls"], "down": st["tel_down"], "lost_down": st["lost_down"],
                      "up": st["tel_up"], "lost_up": st["lost_up"]},
            "off": dict(self.off),
        }

    def trace(self):
        return self.ch.trace()

    def close(self):
        self.ch.close()
