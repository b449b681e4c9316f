"""The checklist of docs/commissioning.md for one station, run automatically, and the round trips.

Each check gives ok (True), a failure (False) or not run (None), with one line of text: what was
seen, the note's section, what to change. The note is Piciorgros, "SPS-Kopplung über MODBUS/IP
im Zeitschlitzfunk" (cited "note §n"). What the note does not say is marked "our choice".

The test blocks (our choice): register 0 and 1 are 0, the note's "undefined state" of the record
and acknowledgement counters (note §2.1, §2.2; no PLC takes it for a record: st_lib treats
record 0 as a reset of an older sender, st_lib/PROTOCOL.md P16, and nothing is open while the
PLCs are stopped), then "PR" "OB", the station, a sequence number and a nonce of this run; the
measurement blocks are padded to the record length with a pattern of the sequence number.
"""
from __future__ import annotations

import random
import time
from dataclasses import dataclass, field

from .link import ModbusExc, NoLink
from .regmap import MDP810, NEW_DATA, TRM810, WRITE_UNCONFIRMED
from .slots import slots_seen, slots_text

CHECKS = ["answers", "quiet", "unit id", "address base", "transfer mode", "block down",
          "bit 4 down", "block up", "bit 4 up"]
MAGIC = (0x5052, 0x4F42)           # "PR" "OB"
L = 8                              # registers of a check block
WATCH_SPAN = 125                   # the write count and the first 124 write registers


@dataclass
class Check:
    name: str
    ok: bool | None
    text: str


@dataclass
class Options:
    timeout: float = 10.0          # s: a block must arrive (and be confirmed) within it
    watch: float = 2.0             # s: watching for a PLC before writing (our choice)
    poll: float = 0.01             # s between the reads that wait for a block
    blocks: int = 10               # measured round trips per direction
    registers: int = 123           # length of the measurement blocks (dynamic mode)
    force: bool = False            # probe although a PLC writes


class Stop(Exception):
    """The station's checks cannot go on (its result is already recorded)."""


@dataclass
class StationResult:
    station: int
    trm: str
    mdp: str
    checks: dict = field(default_factory=dict)
    measure: dict | None = None
    interrupted: bool = False

    def verdict(self):
        for name in CHECKS + ["round trips"]:
            c = self.checks.get(name)
            if c is not None and c.ok is False:
                return c
        return None


def find(data, block):
    """index of block in data, or -(index + 1) of a damaged copy (its header, station, sequence
    number and this run's nonce, but not the rest), or None"""
    n = len(block)
    for i in range(len(data) - n + 1):
        if data[i:i + n] == list(block):
            return i
    for i in range(len(data) - 6):
        if data[i:i + 7] == list(block[:7]):
            return -(i + 1)
    return None


class StationProbe:
    def __init__(self, station, mdp, trm, opts: Options, others=(), log=None, nonce=None):
        self.s, self.mdp, self.trm, self.o = station, mdp, trm, opts
        self.others = others            # (station, TRM endpoint) of the other stations given
        self.r = StationResult(station, trm.text, f"{mdp.text} unit {mdp.unit}")
        self.seq = 0
        self.nonce = nonce if nonce is not None else random.randrange(1, 0x10000)
        self.trm_base = self.mdp_base = 0
        self.log = log or (lambda text: None)

    # -- helpers -----------------------------------------------------------------------------
    def set(self, name, ok, text):
        self.r.checks[name] = Check(name, ok, text)
        self.mdp.tracer.line(ev="probe", st=self.s, check=name, ok=ok, text=text)
        if ok is False:
            raise Stop

    def block(self, n=L):
        self.seq += 1
        b = [0, 0, MAGIC[0], MAGIC[1], self.s, self.seq, self.nonce, (self.s * 257 + self.seq) & 0xFFFF]
        return b + [(self.seq * 31 + j * 7) & 0xFFFF for j in range(n - L)]

    def wait(self, fn, timeout=None):
        """fn() until it returns something not None, or None after timeout"""
        end = time.monotonic() + (self.o.timeout if timeout is None else timeout)
        while True:
            v = fn()
            if v is not None:
                return v
            if time.monotonic() >= end:
                return None
            time.sleep(self.o.poll)

    # -- the checks --------------------------------------------------------------------------
    def run(self):
        try:
            self.answers()
            self.quiet()
            c_down, down_at = self.down()
            self.up(c_down, down_at)
            self.measure()
        except Stop:
            pass
        except KeyboardInterrupt:
            self.r.interrupted = True
            raise
        except (NoLink, ModbusExc) as e:       # a failure the current step did not expect
            name = next((c for c in CHECKS if c not in self.r.checks), "round trips")
            self.r.checks[name] = Check(name, False, str(e))
        return self.r

    def answers(self):
        errs, counts = [], {}
        for ep, reg in ((self.mdp, MDP810.write_count), (self.trm, TRM810.write_count)):
            try:
                counts[ep.ep] = ep.read(reg, 1)[0]
            except ModbusExc as e:
                if ep.ep == "mdp" and e.code == 0x0B:
                    errs.append(f"the MDP has no station {self.s}: it answers unit id {self.s} with "
                                f"exception 0B (gateway target device failed to respond): the "
                                f"station is missing at the MDP or the TRM's station address "
                                f"differs (note §1.1: a register set per station); set the TRM's "
                                f"station address to {self.s} or probe the station it has")
                else:
                    errs.append(str(e))
            except NoLink as e:
                errs.append(str(e) + (f" (over RTU the MDP is silent for a unit id without a "
                                       f"station: is station {self.s} configured at the MDP?)"
                                       if ep.ep == "mdp" and ep.spec["kind"] == "rtu" else ""))
        if errs:
            self.set("answers", False, "; ".join(errs))
        self.set("answers", True, f"TRM {self.trm.text} and MDP {self.mdp.text} unit "
                                  f"{self.mdp.unit} answer (registers 2000 = {counts['trm']}, "
                                  f"9 = {counts['mdp']}; note §3.1, §3.2)")

    def _sample(self):
        return (self.trm.read(TRM810.write_count, WATCH_SPAN),
                self.mdp.read(MDP810.write_count, WATCH_SPAN))

    def quiet(self):
        """Watches the write areas and counts without touching the read data (a read of status
        and count clears nothing): a PLC that writes shows as changes. A write split into single
        registers (FC6, or FC16 in parts) shows as changes of disjoint registers one after the
        other; a modem in dynamic mode refuses such writes (exception 02), so nothing changes
        there and the PLC's client shows the exception (docs/commissioning.md)."""
        end = time.monotonic() + self.o.watch
        prev = self._sample()
        steps = {"trm": [], "mdp": []}
        while time.monotonic() < end:
            time.sleep(max(self.o.poll, 0.02))
            cur = self._sample()
            for k, a, b in (("trm", prev[0], cur[0]), ("mdp", prev[1], cur[1])):
                diff = frozenset(i for i in range(1, WATCH_SPAN) if a[i] != b[i])
                if diff or a[0] != b[0]:
                    steps[k].append(diff)
            prev = cur
        for k, name, first in (("trm", "TRM", TRM810.write_data), ("mdp", "MDP", MDP810.write_data)):
            st = [d for d in steps[k] if d]
            split = any(not (x & y) for x, y in zip(st, st[1:]))
            if split:
                regs = sorted(set().union(*st))[:6]
                self.set("quiet", False,
                         f"a client writes station {self.s}'s block at the {name} in parts: "
                         f"{len(st)} writes in {self.o.watch:g} s changed registers "
                         f"{', '.join(str(first - 1 + i) for i in regs)}... one after the other "
                         f"(FC6 or a split FC16): the modem may send a half-written block "
                         f"(note §1.1.3); write the whole block in one FC16 / FC23 at {first} "
                         f"(note §1.1.2)")
        busy = [f"{name} ({len(steps[k])} changes in {self.o.watch:g} s)"
                for k, name in (("trm", "TRM"), ("mdp", "MDP")) if steps[k]]
        if busy and not self.o.force:
            self.set("quiet", False, f"a PLC writes to station {self.s}: {', '.join(busy)}; "
                                     f"stop the PLCs (the checklist writes test blocks) or "
                                     f"probe anyway with --force")
        self.set("quiet", True, (f"a PLC writes ({', '.join(busy)}): probing anyway (--force)"
                                 if busy else f"no PLC wrote to station {self.s} in "
                                 f"{self.o.watch:g} s"))

    def down(self):
        b = self.block()
        wrote_at = MDP810.write_data
        try:
            self.mdp.write(wrote_at, b)
        except ModbusExc as e:
            if e.code != 2:
                self.set("block down", False, f"{e}: the MDP refuses the test block at 10 "
                                              f"(note §3.1)")
            wrote_at -= 1
            try:
                self.mdp.write(wrote_at, b)
            except ModbusExc:
                self.set("block down", False,
                         f"{e}, and at 9 too: the MDP takes no block of {L} registers at its "
                         f"first write register (dynamic mode needs FC16 at 10, note §1.1.2)")
            self.mdp_base = 1
        t0 = time.monotonic()
        span = L + 4

        polls = [0]

        dead = set()          # other TRMs that did not answer: not asked again (each costs a timeout)

        def elsewhere():
            for s2, trm2 in self.others:
                if s2 in dead:
                    continue
                try:
                    if find(trm2.read(TRM810.read_status, span), b) is not None:
                        return s2, trm2
                except (NoLink, ModbusExc):
                    dead.add(s2)
            return None

        def arrived():
            d = self.trm.read(TRM810.read_status, span)
            i = find(d, b)
            polls[0] += 1
            if i is None and polls[0] % 10 == 0 and elsewhere():   # another TRM got it
                return "elsewhere"
            return (i, d) if i is not None else None
        got = self.wait(arrived)
        if got is None or got == "elsewhere":
            found = elsewhere()        # by its content: what was read stays in the registers
            if found:
                s2, trm2 = found
                self.set("unit id", False,
                         f"the block written to the MDP under unit id {self.s} arrived at "
                         f"the TRM given for station {s2} ({trm2.text}), not at "
                         f"{self.trm.text}: the TRMs' station addresses do not match the "
                         f"unit ids (unit id = station address, docs/protocol.md §4, our "
                         f"reading of note §1.1); set the station address of each TRM, or "
                         f"the unit id of each request of the central PLC")
            self.diagnose_silent(b)
        i, d = got
        self.set("unit id", True, f"the block for unit id {self.s} arrived at this TRM")
        delay = time.monotonic() - t0
        if i < 0:
            self.set("block down", False, f"a test block arrived at the TRM damaged: {d[-i - 1:]} "
                                          f"instead of {b} (note §1.1.3)")
        # where it is says the address bases: 0-based, status and count before it (2198, 2199)
        # (a static MDP that counts from 1 took the block at 10 as its 11: one further)
        if i == 1:
            self.trm_base = 1
        elif i == 3:
            self.mdp_base = 1
        count = d[1] if i >= 2 else d[0]
        return count, delay

    def diagnose_silent(self, b):
        why = []
        try:
            if self.mdp_base:             # the note's register 0 is not addressable then
                raise ModbusExc(2, "MDP")
            fs, status = self.mdp.read(MDP810.field_strength, 2)
            why.append("the MDP never heard station %d (field strengths register 0 = 0, note "
                       "§3.1)" % self.s if fs == 0 else
                       f"field strengths -{fs >> 8} / -{fs & 0xFF} dBm (note §3.1)")
            if status & 0x02:
                why.append("the MDP reports it not reachable (station status bit 1, the "
                           "emulator's reading: the note does not define the bits)")
        except (NoLink, ModbusExc):
            pass
        self.set("block down", False,
                 f"a block written to the MDP for station {self.s} never arrived at the TRM "
                 f"{self.trm.text} within {self.o.timeout:g} s"
                 + (f": {'; '.join(why)}" if why else "")
                 + ": check the MIP mode, the station address, the antenna and the field "
                   "strengths (note §3.1)" + ("" if self.others else "; with every station's "
                                              "TRM given (--trm), the probe also looks there"))

    def up(self, c_down, down_delay):
        trm_base, mdp_base = self.trm_base, self.mdp_base
        # bit 4 of the MDP: the TRM confirmed the block (note §3.1.1)
        st = MDP810.read_status - mdp_base
        ok = self.wait(lambda: True if not self.mdp.read(st, 2)[0] & WRITE_UNCONFIRMED else None)
        bit4_down = ok is not None
        b = self.block()
        wrote_at = TRM810.write_data - trm_base
        try:
            self.trm.write(wrote_at, b)
        except ModbusExc as e:
            if e.code != 2 or trm_base:
                self.set("block up", False, f"{e}: the TRM refuses the test block (note §3.2)")
            wrote_at -= 1
            try:
                self.trm.write(wrote_at, b)
            except ModbusExc:
                self.set("block up", False, f"{e}, and at 2000 too: the TRM takes no block of "
                                            f"{L} registers (dynamic mode: FC16 at 2001, "
                                            f"note §1.1.2)")
            trm_base = 1

        def arrived():
            d = self.mdp.read(MDP810.read_status - mdp_base, L + 4)
            i = find(d, b)
            return (i, d) if i is not None else None
        got = self.wait(arrived)
        up_ok = got is not None and got[0] >= 0
        c_up = (got[1][1] if got[0] >= 2 else got[1][0]) if up_ok else None
        st_t = TRM810.read_status - trm_base
        bit4_up = up_ok and self.wait(
            lambda: True if not self.trm.read(st_t, 2)[0] & WRITE_UNCONFIRMED else None) is not None
        if up_ok and got[0] == 1 and not trm_base:
            mdp_base = 1           # the MDP's 199 shows what its 200 should
        self.trm_base, self.mdp_base = trm_base, mdp_base
        self.address_base()
        idle_trm = self.trm.read(TRM810.write_count - trm_base, 1)[0]
        idle_mdp = self.mdp.read(MDP810.write_count - mdp_base, 1)[0]
        self.mode(idle_trm, idle_mdp, c_down, c_up)
        self.set("block down", True, f"{L} registers written at MDP {MDP810.write_data - mdp_base} "
                                     f"arrived intact at TRM {TRM810.read_data - trm_base} in "
                                     f"{down_delay * 1000:.0f} ms (note §1.1.2, §3.2)")
        if not bit4_down:
            self.set("bit 4 down", False, self.bit4_text("MDP", MDP810.read_status - mdp_base))
        self.set("bit 4 down", True, "the MDP's read status bit 4 cleared: the TRM confirmed "
                                     "(note §3.1.1)")
        if got is None:
            self.set("block up", False, f"a block written at TRM {wrote_at} never arrived at the "
                                        f"MDP (unit id {self.s}) within {self.o.timeout:g} s; "
                                        f"the block down did: check the TRM's MIP mode")
        if got[0] < 0:
            self.set("block up", False, f"a test block arrived at the MDP damaged: "
                                        f"{got[1][-got[0] - 1:]} instead of {b} (note §1.1.3)")
        self.set("block up", True, f"{L} registers written at TRM {wrote_at} arrived intact at MDP "
                                   f"{MDP810.read_data - mdp_base} unit {self.s} (note §1.1.2, §3.1)")
        if not bit4_up:
            self.set("bit 4 up", False, self.bit4_text("TRM", st_t))
        self.set("bit 4 up", True, "the TRM's read status bit 4 cleared: the MDP confirmed "
                                   "(note §3.2.1)")

    def bit4_text(self, name, reg):
        other = "TRM" if name == "MDP" else "MDP"
        return (f"bit 4 (write data unconfirmed) of the {name}'s read status ({reg}) never "
                f"cleared within {self.o.timeout:g} s, although the {other} got the block (note "
                f"§3.1.1, §3.2.1: it clears when the block was confirmed): the blocks' "
                f"bidirectional layout waits for it (st_lib/PROTOCOL.md P9); ask the vendor "
                f"about the firmware, or use the unidirectional layout")

    def address_base(self):
        bad = [n for n, b in (("TRM", self.trm_base), ("MDP", self.mdp_base)) if b]
        if not bad:
            self.set("address base", True, "0-based, as the note's tables: the blocks are at "
                                            "2200 (TRM) and 200 (MDP) after status and count")
            return
        which = " and the ".join(bad)
        status = (TRM810 if "TRM" in bad else MDP810).read_status
        self.set("address base", False,
                 f"the {which} counts its register addresses from 1: the note's register "
                 f"{status} (the read status) is at {status - 1}, "
                 f"every block one register off (note §3.1, §3.2 count from 0); set the modem "
                 f"to 0-based addresses or give every address of the PLC's client one less "
                 f"(docs/wiring.md, check the address base)")

    def mode(self, idle_trm, idle_mdp, c_down, c_up):
        trm_static = idle_trm > 0 or (c_up is not None and c_up != L)
        mdp_static = idle_mdp > 0 or (c_down is not None and c_down != L)
        desc = {True: "static", False: "dynamic"}
        if trm_static != mdp_static:
            self.set("transfer mode", False,
                     f"static / dynamic mismatch: the MDP is {desc[mdp_static]} (register 9 = "
                     f"{idle_mdp} idle, a block of {L} arrives as {c_down}), the TRM "
                     f"{desc[trm_static]} (2000 = {idle_trm} idle, a block of {L} arrives as "
                     f"{c_up}): set the same transfer on both modems (note §1.1, §1.1.1), "
                     f"and xStatic on both PLCs to match")
        if trm_static and idle_trm != idle_mdp:
            self.set("transfer mode", False,
                     f"static on both, but the counts differ: MDP {idle_mdp}, TRM {idle_trm}: "
                     f"set the same count on both modems and uChunkSize to it (note §1.1.1)")
        self.static = idle_trm if trm_static else 0
        self.set("transfer mode", True,
                 f"static with {idle_trm} registers on both modems: set xStatic TRUE and "
                 f"uChunkSize {idle_trm} on both PLCs (note §1.1.1)" if trm_static else
                 "dynamic on both modems: the count registers return to 0 after the "
                 "confirmation (note §1.1.2); set xStatic FALSE on both PLCs")

    # -- the radio's round trips --------------------------------------------------------------
    def one_way(self, send, recv, send_reg, send_status, recv_status, n):
        b = self.block(n)
        t0 = time.monotonic()
        send.write(send_reg, b)

        def arrived():
            d = recv.read(recv_status, 2 + L)
            return d if d[2:2 + L] == b[:L] else None
        if self.wait(arrived) is None:
            return None, None, 0, False, t0
        delivered = time.monotonic() - t0
        whole = recv.read(recv_status + 2, n)
        intact = whole == b
        dup = [0]

        def confirmed():
            d = recv.read(recv_status, 2 + L)
            if d[0] & NEW_DATA and d[2:2 + L] == b[:L]:
                dup[0] += 1          # the same block again: its confirmation was lost
            s = send.read(send_status, 1)[0]
            return True if not s & WRITE_UNCONFIRMED else None
        ok = self.wait(confirmed)
        return delivered, (time.monotonic() - t0) if ok else None, dup[0], intact, t0

    def measure(self):
        n = self.static or self.o.registers
        if not self.o.blocks:
            self.r.checks["round trips"] = Check("round trips", None, "not measured (--blocks 0)")
            return
        res = {"registers": n, "blocks": self.o.blocks}
        for d, send, recv, wreg, sstat, rstat in (
                ("down", self.mdp, self.trm, MDP810.write_data, MDP810.read_status,
                 TRM810.read_status),
                ("up", self.trm, self.mdp, TRM810.write_data, TRM810.read_status,
                 MDP810.read_status)):
            deliv, conf, dups, lost, damaged = [], [], 0, 0, 0
            writes, arrivals = [], []
            for _ in range(self.o.blocks):
                t, c, dup, intact, w = self.one_way(send, recv, wreg, sstat, rstat, n)
                writes.append(w)
                arrivals.append(None if t is None else w + t)
                if t is None:
                    lost += 1
                    continue
                deliv.append(t)
                dups += dup
                damaged += not intact
                if c is not None:
                    conf.append(c)
            # an arrival is seen up to a read period and a read late (and the write takes one)
            answers = sorted(send.latencies + recv.latencies)
            resolution = self.o.poll + 2 * answers[len(answers) // 2]
            res[d] = {"delivered_s": deliv, "confirmed_s": conf, "duplicates": dups,
                      "lost": lost, "damaged": damaged,
                      "slots": slots_seen(writes, arrivals, resolution)}
        self.r.measure = res
        from .sizing import stats_ms
        bad = [f"{d}: {res[d]['lost']} of {self.o.blocks} never arrived" for d in ("down", "up")
               if res[d]["lost"]] + [f"{d}: {res[d]['damaged']} damaged" for d in ("down", "up")
                                     if res[d]["damaged"]]
        text = "; ".join(
            f"{d} " + "/".join(f"{v:g}" for v in stats_ms(res[d]["delivered_s"]).values())
            + f" ms (min/median/p99/max), {res[d]['duplicates']} repeated, "
            + slots_text(res[d]["slots"])
            for d in ("down", "up") if res[d]["delivered_s"])
        text = f"{self.o.blocks} blocks of {n} registers each way: " + text
        if bad:
            self.set("round trips", False, f"{text}; {'; '.join(bad)}")
        self.set("round trips", True, text)
