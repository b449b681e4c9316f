"""mip-peer: a MIP peer (outstation or central) that follows only the Piciorgros note.

Example: mip-peer central --port 15020 --unit 1 --expect 1 --out received.json
         mip-peer scada --port 15030 --out entries.jsonl (SOE handshake master, mippeer/scada.py)
         mip-peer unicos --port 15040 --pair 15041 --out events.jsonl (WinCC OA UNICOS stand-in)
"""

import argparse
import json
import os
import random
import signal
import sys
import time

from .modem import Modem, ModemError
from .peer import Peer


def logger_records(count, size, seed):
    """Deterministic logger data: `count` records of `size` registers."""
    rng = random.Random(seed)
    return [[rng.randrange(65536) for _ in range(size)] for _ in range(count)]


class _Parser(argparse.ArgumentParser):
    def error(self, message):          # one line, not usage + message
        self.exit(2, f"{self.prog}: error: {message}\n")


def parse_args(argv):
    p = _Parser(prog="mip-peer", description=__doc__.splitlines()[0])
    p.add_argument("role", choices=["outstation", "central"])
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True, help="Modbus TCP port of the modem")
    p.add_argument("--unit", type=int, default=1, help="unit id (at the MDP: the station address)")
    p.add_argument("--layout", choices=["uni", "bi"], default="uni",
                   help="uni: note 2.1 (one counter); bi: note 2.2 (two counters)")
    reading = p.add_mutually_exclusive_group()
    reading.add_argument("--strict", dest="lenient", action="store_false", default=False,
                         help="receiver accepts only the next number (default)")
    reading.add_argument("--lenient", dest="lenient", action="store_true",
                         help="receiver also takes record 1 as a new transfer; sender restarts "
                              "with record 1 on acknowledgement 0")
    p.add_argument("--drive", choices=["polled", "spontaneous"], default="spontaneous")
    p.add_argument("--records", type=int, default=0, help="records to send (generated logger data)")
    p.add_argument("--record-size", type=int, default=122, help="payload registers per record")
    p.add_argument("--seed", type=int, default=1, help="seed of the generated logger data")
    p.add_argument("--expect", type=int, default=0, help="stop after this many received transfers")
    p.add_argument("--period", type=float, default=0.05, help="seconds between modem reads")
    p.add_argument("--retransmit", type=float, default=2.0, help="spontaneous resend timeout, s")
    p.add_argument("--request", type=float, default=1.0, help="polled request interval, s")
    p.add_argument("--static-registers", type=int, default=0,
                   help="static MIP mode: write this many registers every time (0: dynamic)")
    p.add_argument("--linger", type=float, default=1.0,
                   help="keep answering this many seconds after the work is done")
    p.add_argument("--timeout", type=float, default=60.0, help="give up after this many seconds")
    p.add_argument("--events", action="store_true",
                   help="print one line per accepted record and per acknowledged record")
    p.add_argument("--out", help="keep the received transfers as JSON in this file")
    a = p.parse_args(argv)
    header = 2 if a.layout == "bi" else 1
    if a.records < 0 or a.records > 65535:
        p.error("--records must be 0..65535")
    if a.records and not 1 <= a.record_size <= 123 - header:
        p.error(f"--record-size must be 1..{123 - header} for the {a.layout} layout")
    if not 0 <= a.static_registers <= 123:
        p.error("--static-registers must be 0..123 (one FC16 carries at most 123)")
    return a


def received(peer):
    """What the peer's receiver holds (the --out document)."""
    r = peer.receiver
    return {"transfers": r.transfers, "open": r.current, "abandoned": r.abandoned,
            "accepted": r.accepted, "duplicates": r.duplicates, "unexpected": r.unexpected}


class Loop:
    """The peer's work one round at a time: read the modem, step the peer, write its block, and
    note what happened (the --events lines). The command runs the rounds in real time; a
    simulation can run them at its own (virtual) times on a Modem.in_process."""

    def __init__(self, peer, modem):
        self.peer, self.modem = peer, modem
        self.events = []            # ("accepted" | "acknowledged", record number), in order
        self._accepted = self._acked = 0

    def round(self, now):
        """One round at `now` (seconds, any origin); returns the events it added."""
        block = self.peer.step(now, self.modem.read())
        if block is not None:
            self.modem.write(block)
        new = []
        r, s = self.peer.receiver, self.peer.sender
        if r is not None and len(r.accepted) > self._accepted:
            new += [("accepted", n) for n in r.accepted[self._accepted:]]
            self._accepted = len(r.accepted)
        if s is not None and s.index != self._acked:
            if s.index > self._acked:
                new += [("acknowledged", n) for n in s._numbers[self._acked : s.index]]
            self._acked = s.index
        self.events += new
        return new

    def seen(self, kind, number):
        return (kind, number) in self.events


def _write_out(path, peer):
    doc = received(peer)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f)
    os.replace(tmp, path)


class _Stop(Exception):
    pass


def _on_term(*_):
    raise _Stop()


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["scada"]:
        # the SCADA master of the pull way (issue 35): its own options, peers/mippeer/scada.py
        from .scada import main as scada_main
        return scada_main(argv[1:])
    if argv[:1] == ["unicos"]:
        # the WinCC OA UNICOS-driver stand-in of the push way (issue 35), peers/mippeer/unicos.py
        from .unicos import main as unicos_main
        return unicos_main(argv[1:])
    a = parse_args(argv)
    records = logger_records(a.records, a.record_size, a.seed) if a.records else None
    try:
        peer = Peer(a.role, records, layout=a.layout, drive=a.drive, lenient=a.lenient,
                    retransmit_s=a.retransmit, request_s=a.request,
                    static_registers=a.static_registers)
    except ValueError as e:
        print(f"mip-peer: error: {e}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, _on_term)
    modem = Modem(a.host, a.port, "trm" if a.role == "outstation" else "mdp", a.unit)
    loop = Loop(peer, modem)
    start = time.monotonic()
    done_at = None
    stopped = None
    try:
        modem.connect()
        while True:
            now = time.monotonic() - start
            new = loop.round(now)
            if a.events:
                for kind, n in new:
                    print(f"{kind} {n}", flush=True)
            if a.out and any(kind == "accepted" for kind, _ in new):
                _write_out(a.out, peer)
            r = peer.receiver
            finished = peer.done and len(r.transfers if r else []) >= a.expect
            if finished and done_at is None:
                done_at = now
            if done_at is not None and now - done_at >= a.linger:
                break
            if now > a.timeout:
                print(f"mip-peer: error: timeout after {a.timeout:g} s", file=sys.stderr)
                return 1
            time.sleep(a.period)
    except ModemError as e:
        print(f"mip-peer: error: {e}", file=sys.stderr)
        return 1
    except _Stop:
        stopped = 0      # SIGTERM: the normal way a test or a supervisor ends the peer
    except KeyboardInterrupt:
        stopped = 130
    finally:
        modem.close()
    if a.out and peer.receiver:
        _write_out(a.out, peer)
    if stopped is not None:
        return stopped
    print(f"mip-peer: {a.role} done: sent={'yes' if records else 'nothing'} "
          f"received_transfers={len(peer.receiver.transfers) if peer.receiver else 0} "
          f"writes={peer.writes} repeats={peer.repeats} "
          f"duplicates={peer.receiver.duplicates if peer.receiver else 0} "
          f"unexpected={peer.receiver.unexpected if peer.receiver else 0}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
