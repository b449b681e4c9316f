"""Training tool: one logger transfer with the st_lib blocks over the emulated radio, in virtual
time, with the emulator's fault options; prints what each side saw and writes a trace.

    .venv/bin/python docs/tools/mipsim.py [--records 5] [--payload 122] [--polled]
        [--loss-up P] [--loss-down P] [--burst L] [--seed S] [--timeout-ms 2000]
        [--restart outstation|central --restart-at-ms T] [--bidirectional]
        [--limit-s 120] [--trace FILE]

Nothing real runs: two soft PLCs (st_lib built with stc into the soft-PLC runtime, whose own
Modbus master does the requests) and the emulator core run in the co-simulation kernel
(build/cosim/libmipcosim.so, built by `make`) in lockstep, one scan every 10 ms of virtual time,
so a run of minutes takes seconds and the same options give the same result. Draw the
trace with docs/tools/seqdiag.py. Exit status 0 when every transfer completed and the data
arrived unchanged, 1 otherwise, 2 for bad options.
"""
from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from mipdocs.chainsim import MS, Chain, ChainError, Side
from mipdocs.gen_traces import WORK, logger_data


def parse(argv):
    ap = argparse.ArgumentParser(prog="mipsim",
                                 description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--records", type=int, default=5, help="full records in the transfer")
    ap.add_argument("--payload", type=int, default=None,
                    help="payload registers per record (default: the most, 122 or 121)")
    ap.add_argument("--polled", action="store_true", help="polled drive (default spontaneous)")
    ap.add_argument("--bidirectional", action="store_true",
                    help="MIP_Link on both sides, the central sends too")
    ap.add_argument("--loss-up", type=float, default=0.0)
    ap.add_argument("--loss-down", type=float, default=0.0)
    ap.add_argument("--burst", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout-ms", type=int, default=2000, help="tTimeout of the blocks")
    ap.add_argument("--read-ms", type=int, default=100,
                    help="period of the PLCs' reads (a multiple of 10, at least 20)")
    ap.add_argument("--restart", choices=["outstation", "central"],
                    help="restart this PLC (all its state lost) at --restart-at-ms")
    ap.add_argument("--restart-at-ms", type=int, default=1000)
    ap.add_argument("--limit-s", type=float, default=120.0, help="give up after this virtual time")
    ap.add_argument("--trace", help="write the JSON-lines trace here")
    a = ap.parse_args(argv)
    header = 2 if a.bidirectional else 1
    if a.payload is None:
        a.payload = 123 - header
    if not 1 <= a.payload <= 123 - header:
        ap.error(f"--payload must be 1..{123 - header}")
    if a.records < 1:
        ap.error("--records must be at least 1")
    for name in ("loss_up", "loss_down"):
        if not 0.0 <= getattr(a, name) <= 1.0:
            ap.error(f"--{name.replace('_', '-')} must be 0..1")
    if a.burst and a.burst < 1:
        ap.error("--burst must be 0 or at least 1")
    if a.timeout_ms < 10 or a.read_ms < 20 or a.read_ms % 10:
        # a read is a level handshake with the runtime's master: trigger up, done, trigger
        # down, so at most one read every other scan
        ap.error("--timeout-ms must be >= 10 and --read-ms a multiple of 10, at least 20")
    return a


def main(argv=None):
    if hasattr(signal, "SIGPIPE"):
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)    # `mipsim ... | head -1` stays quiet
    a = parse(argv)
    role = "link" if a.bidirectional else None
    chunk = a.payload + (2 if a.bidirectional else 1)
    data_o = logger_data(a.records * a.payload, a.seed)
    o = Side("outstation", role or "sender", data=data_o, polled=a.polled, chunk=chunk,
             timeout_ms=a.timeout_ms, read_ms=a.read_ms)
    data_c = logger_data(a.records * a.payload, a.seed + 1000) if a.bidirectional else []
    c = Side("central", role or "receiver", data=data_c, polled=a.polled, chunk=chunk,
             timeout_ms=a.timeout_ms, read_ms=a.read_ms, read_phase_ms=a.read_ms // 2)
    try:
        ch = Chain(WORK, o, c, loss_up=a.loss_up, loss_down=a.loss_down, burst=a.burst,
                   seed=a.seed)
    except ChainError as e:
        print(f"mipsim: error: {e}", file=sys.stderr)
        return 2
    limit = int(a.limit_s * 1000)
    restarted = a.restart is None

    def finished():
        return o.send_done and c.send_done and ch.t > 0

    while ch.t < limit * MS and not finished():
        if not restarted and ch.t >= a.restart_at_ms * MS:
            ch.restart(o if a.restart == "outstation" else c)
            restarted = True
        ch.step()
    ch.run_until(lambda: False, 300)
    if a.trace:
        try:
            Path(a.trace).write_text("\n".join(ch.trace()) + "\n")
        except OSError as e:
            print(f"mipsim: error: {a.trace}: {e.strerror}", file=sys.stderr)
            ch.close()
            return 2
    st = ch.stats(1)
    ok = finished()
    print(f"mipsim: {'complete' if ok else 'NOT complete'} after {ch.t / 1e9:.2f} s virtual time")
    print(f"radio: polls={st['polls']} telegrams down={st['tel_down']} (lost {st['lost_down']}) "
          f"up={st['tel_up']} (lost {st['lost_up']}) duplicates down={st['dup_down']} "
          f"up={st['dup_up']}")
    for side, other, data in ((o, c, data_o), (c, o, data_c)):
        fb = side.fbv
        if side.role == "sender":
            print(f"outstation MIP_Sender: records acknowledged={fb('udiRecords')} "
                  f"retransmissions={fb('udiRetransmissions')} "
                  f"unexpected acks={fb('udiUnexpectedAcks')} errors={side.errors or 'none'}")
        elif side.role == "receiver":
            print(f"central MIP_Receiver: records delivered={fb('udiRecords')} "
                  f"duplicates={fb('udiDuplicates')} unexpected={fb('udiUnexpected')} "
                  f"failed transfers={fb('udiFailedTransfers')} errors={side.errors or 'none'}")
        else:
            print(f"{side.name} MIP_Link: sent={fb('udiRecordsSent')} "
                  f"received={fb('udiRecordsReceived')} retransmissions="
                  f"{fb('udiRetransmissions')} duplicates={fb('udiDuplicates')} "
                  f"unexpected={fb('udiUnexpected')} errors={side.errors or 'none'}")
        if data and ok:
            if not other.transfers or other.transfers[-1] != data:
                print(f"mipsim: the {other.name} did not receive the {side.name}'s data "
                      f"unchanged")
                ok = False
    ch.close()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
