"""How long a read-out takes, ours against the note-only peer (issue 11's timing targets).

One uni-directional read-out of N records (dynamic mode, spontaneous drive, no loss) from an
outstation to a central over build/emulator/mip-emulator, in real time, with four pairings:

  note -> note            two mip-peer processes (peers/: the note alone), the reference
  ours -> note-strict     our outstation (plc/outstation.st, MIP_Sender) to a strict note central
  ours -> note-lenient    ... to a lenient note central
  ours -> ours            our outstation to our central (plc/central.st, MIP_Receiver)

The receiving side starts first and settles (its first acknowledgement reached the station's
modem); then the sender starts. Every figure comes from the emulator's trace (one clock):

  start     the sender's first Modbus request to its modem (it is up and talking)
  record 1  its first write of a block whose register 0 is 1
  done      the acknowledgement 16#FFFF delivered into the station's modem (the sender can see
            that the read-out is complete)
  read-out  done less the wait of record 1 for its first poll slot (when the sender started
            relative to the radio's poll cycle is chance, not protocol)
  per record              (done - record 1) / (N - 1)
  ack -> next write       for each record n > 1: from the sender's first read of its modem after
                          the acknowledgement n-1 arrived there, to its write of record n

Used by the bench (mipbench.readout: the `readout_realistic` and `record_reaction` lines) and
tests/interop/test_interop_timing.py.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path

from mipcosim.trace import read_trace
from mipprobe.regmap import TRM810

from .cell import (FAST_RADIO, REALISTIC_RADIO, MatrixError, PeerProc, build_programs, L,
                     demo, start_emulator)

PAIRS = ("note->note", "ours->note-strict", "ours->note-lenient", "ours->ours")
FFFF = 0xFFFF
TRM_READ, TRM_WRITE = TRM810.read_status, TRM810.write_data
SCAN_MS = 10                                   # plc/*.st task interval


@dataclass
class Readout:
    pair: str
    radio: str
    records: int
    record1_s: float = 0.0        # all times: seconds after `start`
    done_s: float = 0.0
    slot_wait_s: float = 0.0      # record 1 written -> the radio starts carrying it
    ack_air_ms: float = 0.0       # mean air time of a telegram carrying an acknowledgement down
    per_record_ms: float = 0.0
    reaction_ms: list = field(default_factory=list)   # ack -> next write, per record n > 1

    @property
    def readout_s(self):
        """done, less the wait for the first poll slot: when the sender started relative to
        the radio's poll cycle is chance (process start-up), not protocol."""
        return self.done_s - self.slot_wait_s

    @property
    def reaction_median_ms(self):
        return statistics.median(self.reaction_ms) if self.reaction_ms else float("nan")


def analyse(trace: Path, pair: str, radio: str, records: int) -> Readout:
    """The figures of one read-out from the emulator's JSON-lines trace (station 1)."""
    ev = read_trace(trace)
    trm = [e for e in ev if e.get("ev") == "modbus" and e.get("ep") == "trm" and e.get("st") == 1]
    if not trm:
        raise MatrixError(f"{pair}: the sender never talked to its modem")
    t_start = trm[0]["t"]

    def first_write(number, after=0):
        for e in trm:
            if e["t"] >= after and e.get("fc") == 16 and e.get("wa") == TRM_WRITE and \
                    e.get("w0") == number and e.get("exc") == 0:
                return e["t"]
        return None

    def ack_arrival(number, after):
        for e in ev:
            if e.get("ev") == "radio" and e["dir"] == "down" and e["st"] == 1 and \
                    e.get("regs", 0) > 0 and e.get("r0") == number and not e["lost"] and \
                    e["t"] >= after:
                return e["t"]
        return None

    numbers = list(range(1, records)) + [FFFF]
    t1 = first_write(1)
    if t1 is None:
        raise MatrixError(f"{pair}: record 1 was never written")
    r = Readout(pair, radio, records, record1_s=(t1 - t_start) / 1e9)
    up1 = next((e for e in ev if e.get("ev") == "radio" and e["dir"] == "up" and
                e["st"] == 1 and e.get("regs", 0) > 0 and e.get("r0") == 1 and e["t0"] >= t1),
               None)
    if up1 is not None:
        r.slot_wait_s = (up1["t0"] - t1) / 1e9
    t_prev = t1
    for prev, nxt in zip(numbers, numbers[1:]):
        t_ack = ack_arrival(prev, t_prev)
        t_w = first_write(nxt, t_prev)
        if t_ack is None or t_w is None:
            raise MatrixError(f"{pair}: record {nxt} did not follow the acknowledgement {prev}")
        t_read = next((e["t"] for e in trm if e["t"] >= t_ack and e.get("fc") in (3, 4)
                       and e.get("ra") == TRM_READ), None)
        if t_read is not None and t_read <= t_w:
            r.reaction_ms.append((t_w - t_read) / 1e6)
        t_prev = t_w
    downs = [e["t"] - e["t0"] for e in ev if e.get("ev") == "radio" and e["dir"] == "down" and
             e["st"] == 1 and e.get("regs", 0) > 0]
    r.ack_air_ms = statistics.mean(downs) / 1e6 if downs else 0.0
    t_done = ack_arrival(FFFF, t_prev)
    if t_done is None:
        raise MatrixError(f"{pair}: the acknowledgement of 16#FFFF never reached the station")
    r.done_s = (t_done - t_start) / 1e9
    r.per_record_ms = (t_done - t1) / 1e6 / max(1, records - 1)
    return r


class _Run:
    def __init__(self, pair, radio, records, payload, progs, workdir: Path, seed, timeout_ms):
        self.pair, self.radio, self.records, self.payload = pair, radio, records, payload
        self.progs, self.dir, self.seed, self.timeout_ms = progs, workdir, seed, timeout_ms
        self.procs = demo.Procs()
        self.peers = []
        self.slaves = []
        self.sender_done = None

    def _peer(self, role, reading, port, out):
        args = [role, "--port", str(port), "--unit", "1", "--layout", "uni", f"--{reading}",
                "--drive", "spontaneous", "--period", "0.01", "--retransmit",
                str(self.timeout_ms / 1000), "--request", str(self.timeout_ms / 1000),
                "--timeout", "600", "--expect", "1000000", "--out", str(out)]
        if role == "outstation":
            args += ["--records", str(self.records), "--record-size", str(self.payload),
                     "--seed", "11"]
        p = PeerProc(args, self.dir / f"peer-{role}.log")
        self.peers.append(p)
        return p

    def _ours(self, role):
        conf = self.dir / f"{role}.conf"
        conf.write_text(L.outstation_config(self.trm) if role == "outstation"
                        else L.central_config(self.mdp, 1))
        port = demo.free_port()
        exe = self.progs[role, False].executable
        self.procs.start(role, [str(exe), "-c", str(conf), "-s", f"127.0.0.1:{port}"],
                         self.dir / f"{role}.log")
        slave = demo.Slave(port)
        slave.connect(time.monotonic() + 10)
        self.slaves.append(slave)
        params = L.Params(records=self.records, payload=self.payload, session=7, station=1,
                          timeout_ms=self.timeout_ms, chunk=123, max_retries=0)
        slave.write(0, params.words())
        return slave

    def _check(self):
        self.procs.check_alive()
        for p in self.peers:
            p.alive_or_raise()

    def run(self, cap_s) -> Readout:
        radio = REALISTIC_RADIO if self.radio == "realistic" else FAST_RADIO
        sender, receiver = self.pair.split("->")
        try:
            self.mdp, self.trm = start_emulator(self.procs, self.dir, self.seed, radio)
            trace = self.dir / "trace.jsonl"
            if receiver == "ours":
                self._ours("central")
            else:
                reading = receiver.split("-", 1)[1] if "-" in receiver else "strict"
                self._peer("central", reading, self.mdp, self.dir / "got.json")
            # settle: the receiver's first acknowledgement (0) reached the station's modem
            time.sleep(1.0 if self.radio == "realistic" else 0.3)
            if sender == "ours":
                slave = self._ours("outstation")
                done = lambda: slave.read(L.peer_base(1), L.S_ALL + 1)[L.S_ALL] == 1   # noqa: E731
            else:
                peer = self._peer("outstation", "strict", self.trm, self.dir / "sent.json")
                done = lambda: peer.seen("acknowledged", FFFF)              # noqa: E731
            t0 = time.monotonic()
            while not done():
                self._check()
                if time.monotonic() - t0 > cap_s:
                    raise MatrixError(f"{self.pair}: the read-out of {self.records} records did "
                                      f"not complete in {cap_s:g} s")
                time.sleep(0.02)
            time.sleep(0.1)
        except demo.DemoError as e:
            raise MatrixError(f"{self.pair}: {e}") from None
        finally:
            for p in self.peers:
                p.stop()
            for s in self.slaves:
                s.close()
            self.procs.stop()       # the emulator flushes its trace on SIGTERM
        return analyse(trace, self.pair, self.radio, self.records)


def readout(pair, radio, records, workdir: Path, progs=None, payload=122, seed=1,
            timeout_ms=2000, cap_s=120.0) -> Readout:
    """One read-out of `records` records for `pair` (one of PAIRS) on the `radio` ("fast" or
    "realistic"). `progs`: build_programs() output, built here when None."""
    if pair not in PAIRS:
        raise ValueError(f"pair {pair!r}: one of {', '.join(PAIRS)}")
    workdir.mkdir(parents=True, exist_ok=True)
    if progs is None:
        progs = build_programs(workdir / "build")
    return _Run(pair, radio, records, payload, progs, workdir, seed, timeout_ms).run(cap_s)
