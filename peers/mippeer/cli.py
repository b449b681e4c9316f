"""mip-peer: an independent MIP peer (outstation or central) talking Modbus TCP to a modem.

Example: mip-peer central --port 15020 --unit 1 --expect 5 --out received.json
"""

import argparse
import json
import random
import sys
import time

from .modem import Modem, ModemError
from .peer import Peer


def logger_records(count, size, seed):
    """Deterministic logger data: `count` records of `size` registers."""
    rng = random.Random(seed)
    return [[rng.randrange(65536) for _ in range(size)] for _ in range(count)]


def parse_args(argv):
    p = argparse.ArgumentParser(prog="mip-peer", description=__doc__.splitlines()[0])
    p.add_argument("role", choices=["outstation", "central"])
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True, help="Modbus TCP port of the modem")
    p.add_argument("--unit", type=int, default=1, help="unit id (at the MDP: the station address)")
    p.add_argument("--layout", choices=["uni", "bi"], default="uni")
    p.add_argument("--drive", choices=["polled", "spontaneous"], default="spontaneous")
    p.add_argument("--records", type=int, default=0, help="records to send (generated logger data)")
    p.add_argument("--record-size", type=int, default=122, help="payload registers per record")
    p.add_argument("--seed", type=int, default=1, help="seed of the generated logger data")
    p.add_argument("--expect", type=int, default=0, help="stop after this many received transfers")
    p.add_argument("--period", type=float, default=0.05, help="seconds between modem reads")
    p.add_argument("--retransmit", type=float, default=2.0, help="spontaneous resend timeout, s")
    p.add_argument("--request", type=float, default=1.0, help="polled request interval, s")
    p.add_argument("--static-registers", type=int, default=0, help="static mode: N mirrored registers")
    p.add_argument("--timeout", type=float, default=60.0, help="give up after this many seconds")
    p.add_argument("--out", help="write received transfers as JSON to this file")
    a = p.parse_args(argv)
    header = 2 if a.layout == "bi" else 1
    if a.records and not 1 <= a.record_size <= 123 - header:
        p.error(f"--record-size must be 1..{123 - header} for the {a.layout} layout")
    return a


def main(argv=None):
    a = parse_args(argv)
    records = logger_records(a.records, a.record_size, a.seed) if a.records else None
    try:
        peer = Peer(a.role, records, layout=a.layout, drive=a.drive, retransmit_s=a.retransmit,
                    request_s=a.request, static_registers=a.static_registers)
    except ValueError as e:
        print(f"mip-peer: error: {e}", file=sys.stderr)
        return 2
    modem = Modem(a.host, a.port, "trm" if a.role == "outstation" else "mdp", a.unit)
    start = time.monotonic()
    try:
        modem.connect()
        while True:
            now = time.monotonic() - start
            block = peer.step(now, modem.read())
            if block is not None:
                modem.write(block)
            received = peer.receiver.transfers if peer.receiver else []
            if peer.done and len(received) >= a.expect:
                break
            if now > a.timeout:
                print(f"mip-peer: error: timeout after {a.timeout:g} s", file=sys.stderr)
                return 1
            time.sleep(a.period)
    except ModemError as e:
        print(f"mip-peer: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        modem.close()
    if a.out and peer.receiver:
        with open(a.out, "w") as f:
            json.dump({"transfers": peer.receiver.transfers, "aborted": peer.receiver.aborted,
                       "duplicates": peer.receiver.duplicates}, f)
    print(f"mip-peer: {a.role} done: sent={'yes' if records else 'nothing'} "
          f"received_transfers={len(peer.receiver.transfers) if peer.receiver else 0} "
          f"writes={peer.writes} "
          f"aborted_transfers={len(peer.receiver.aborted) if peer.receiver else 0} "
          f"peer_resets={peer.sender.peer_resets if peer.sender else 0}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
