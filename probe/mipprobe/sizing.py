"""The sizing rules of the blocks' parameters: the time a Modbus RTU line takes and what a
serial link adds to the blocks' repeat timeout tTimeout (the table of docs/serial.md;
tests/docs/test_docs_serial.py compares it with this module), and the parameters mip-probe
recommends from the round trips it measured (`recommend`, docs/commissioning.md). One
implementation for the docs' table, the tool and what the chain's hand-over to a polling SCADA
adds (handover_timeout_ms, mipdemo.chain: the steps a round trip waits for in series, times
their duration); the demo's rule (mipcosim.cli.link_timeout_ms,
plc/demo.py) is older and up to 24 ms lower above 19,200 baud (docs/serial.md says so).

    python -m mipprobe.sizing        # prints the tTimeout table of docs/serial.md

A character is 1 start + data + parity + stop bits; frames are separated by t3.5, 3.5
characters, fixed at 1.75 ms above 19,200 baud (MODBUS over Serial Line Specification and
Implementation Guide V1.02, section 2.5.1.1). An exchange is a request and its answer, each
after a gap.
"""
from __future__ import annotations

import math
import sys

BAUDS = (9600, 19200, 38400, 57600, 115200)
RECORD_REGISTERS = (16, 32, 64, 123)

# Our choice, the demo's since issue 27 (no manual speaks of it): the timeout covers eight of a
# record's largest exchanges on a line. In series in one round trip there are five exchanges
# (the record's FC16; the central's status read and block read; the acknowledgement's FC16;
# the outstation's read of it), and each may wait for the exchange in progress on its line.
TIMEOUT_EXCHANGES = 8


def char_s(baud: int, frame: str = "8E1") -> float:
    """seconds per character: 1 start + data + parity + stop bits"""
    return (1 + int(frame[0]) + (frame[1] != "N") + int(frame[2])) / baud


def gap_s(baud: int, frame: str = "8E1") -> float:
    """t3.5 (V1.02 section 2.5.1.1)"""
    return 0.00175 if baud > 19200 else 3.5 * char_s(baud, frame)


def exchange_s(baud: int, request_chars: int, answer_chars: int, frame: str = "8E1") -> float:
    """a request and its answer, each after a gap"""
    return (request_chars + answer_chars) * char_s(baud, frame) + 2 * gap_s(baud, frame)


def record_exchange_chars(registers: int) -> int:
    """characters of a record's largest exchange, request and answer: its FC16 (9 + 2n, answer
    8) and the read of status, count and record (8, answer 5 + 2 (2 + n)) are both 17 + 2n"""
    return 17 + 2 * registers


def added_ms(steps: int, step_s: float) -> int:
    """docs/serial.md's rule: what `steps` steps of step_s seconds, waited for one after the
    other within a round trip, add to the tTimeout of the link without them; ms, rounded up
    to 10 ms"""
    return int(math.ceil(steps * step_s * 100 - 1e-9)) * 10


def link_timeout_ms(baud: int, registers: int = 123, frame: str = "8E1",
                    exchanges: int = TIMEOUT_EXCHANGES) -> int:
    """what a serial link at baud adds to tTimeout for records of `registers` registers, ms
    (rounded up to 10 ms)"""
    return added_ms(exchanges, exchange_s(baud, record_exchange_chars(registers), 0, frame))


def handover_polls(entries: int, per_poll: int) -> int:
    """SCADA polls a record of `entries` relay entries waits for at a central that acknowledges
    it over the radio only once the SCADA took its last entry (plc/central_soe.st,
    docs/chain.md), the SCADA taking at most `per_poll` entries a poll (3 in the SOE handshake:
    mippeer.scada.BLOCKS): one poll per `per_poll` entries in series, and one more, the poll the
    record arrived just after (our choice, the analogue of the exchange in progress)"""
    return -(-entries // per_poll) + 1


def handover_timeout_ms(entries: int, per_poll: int, poll_s: float) -> int:
    """what that hand-over adds to tTimeout with a poll every poll_s seconds, ms (rounded up to
    10 ms)"""
    return added_ms(handover_polls(entries, per_poll), poll_s)


def timeout_table(bauds=BAUDS, registers=RECORD_REGISTERS, frame: str = "8E1") -> str:
    """the Markdown table of docs/serial.md: ms to add to tTimeout, per baud and record size"""
    head = "| baud (" + frame + ") | " + " | ".join(f"{r} registers" for r in registers) + " |"
    rule = "|---|" + "---|" * len(registers)
    rows = [f"| {b:,} | " + " | ".join(f"{link_timeout_ms(b, r, frame):,} ms" for r in registers) + " |"
            for b in bauds]
    return "\n".join([head, rule] + rows) + "\n"



# ---- the parameters from the measured radio (mip-probe) --------------------------------------
# Our choices (no manual speaks of them; docs/commissioning.md "What the probe recommends"):
TIMEOUT_MARGIN = 2.0        # tTimeout = 2 x the slowest record round trip seen (p99 + p99 + reads)
TIMEOUT_STEP_MS = 100       # rounded up to 100 ms
TIMEOUT_MIN_MS = 200
TRANSFER_TIMEOUTS = 5       # tTransferTimeout = 5 x tTimeout ("a few times", wiring.md)
READ_PERIOD_MIN_MS, READ_PERIOD_MAX_MS = 50, 500   # wiring.md: 100-500 ms; fast radios lower
REPLY_TIMEOUT_MIN_MS = 1000  # the glue's per-request timeout: 10 x the slowest answer, >= 1 s
DESIGN_LOSS = 0.3            # the loss a finite uMaxRetries must ride through
FAIL_RATE = 1e-6             # ... failing less than once in a million records


def percentile(xs, q):
    """q-th percentile (0..100) of the samples, nearest rank; None for no samples"""
    xs = sorted(xs)
    if not xs:
        return None
    k = max(0, min(len(xs) - 1, math.ceil(q / 100 * len(xs)) - 1))
    return xs[k]


def stats_ms(xs):
    """min / median / p99 / max of samples in s, as ms (1 decimal)"""
    if not xs:
        return None
    return {k: round(v * 1000, 1) for k, v in (("min", min(xs)), ("median", percentile(xs, 50)),
                                                ("p99", percentile(xs, 99)), ("max", max(xs)))}


def _up(ms, step):
    return int(math.ceil(ms / step - 1e-9)) * step


def recommend(down_s, up_s, answer_s, baud=None, frame="8E1", registers=123,
              design_loss=DESIGN_LOSS):
    """The blocks' parameters from the measured radio: down_s / up_s the delivery times of the
    test blocks (a write at one modem until the other modem's read area shows it), answer_s the
    modems' answer times to single Modbus requests, all in s, over every station; baud: the
    PLC-modem link is Modbus RTU at that rate (its line time is added as in docs/serial.md).
    Returns a dict of ints (ms, counts) and the reasons, one line each."""
    if not down_s or not up_s:
        raise ValueError("no round trips measured: nothing to size the parameters from")
    cycle_ms = max(max(down_s), max(up_s)) * 1000
    # rule C3 (st_lib/PROTOCOL.md): each side reads at least once per radio poll cycle
    read_ms = max(READ_PERIOD_MIN_MS, min(READ_PERIOD_MAX_MS, int(cycle_ms / 2 // 10 * 10)))
    rt_ms = (percentile(down_s, 99) + percentile(up_s, 99)) * 1000 + 2 * read_ms
    line_ms = link_timeout_ms(baud, registers, frame) if baud else 0
    t_timeout = max(TIMEOUT_MIN_MS, _up(TIMEOUT_MARGIN * rt_ms, TIMEOUT_STEP_MS)) + line_ms
    reply_ms = max(REPLY_TIMEOUT_MIN_MS, _up(10 * max(answer_s) * 1000, 100)) if answer_s \
        else REPLY_TIMEOUT_MIN_MS
    # an attempt fails when its record or its acknowledgement is lost (the modems repeat a lost
    # block themselves, so this overestimates); retries until the failure rate is FAIL_RATE
    q = 1 - (1 - design_loss) ** 2
    retries = max(3, math.ceil(math.log(FAIL_RATE) / math.log(q))) if 0 < q < 1 else 3
    p = {"tTimeout_ms": t_timeout, "uMaxRetries": 0, "uMaxRetries_finite": retries,
         "tTransferTimeout_ms": TRANSFER_TIMEOUTS * t_timeout, "read_period_ms": read_ms,
         "reply_timeout_ms": reply_ms, "round_trip_ms": round(rt_ms, 1),
         "poll_cycle_ms": round(cycle_ms, 1), "line_ms": line_ms,
         # the prediction: a tTimeout below the slowest round trip seen retransmits records
         # needlessly; an upper bound (the test blocks are full both ways, an acknowledgement
         # is shorter than a record)
         "retransmits_below_ms": int(math.ceil(rt_ms)) + line_ms}
    p["why"] = {
        "tTimeout_ms": f"{TIMEOUT_MARGIN:g} x the slowest record round trip (p99 down "
                       f"{percentile(down_s, 99) * 1000:.0f} ms + p99 up "
                       f"{percentile(up_s, 99) * 1000:.0f} ms + 2 reads of {read_ms} ms), "
                       f"rounded up to {TIMEOUT_STEP_MS} ms"
                       + (f", + {line_ms} ms for the RTU line at {baud} baud {frame} "
                          f"(docs/serial.md)" if line_ms else ""),
        "uMaxRetries": "0 = unlimited: a logger must arrive eventually (wiring.md); "
                       f"{retries} if the application wants xError: fails less than once in "
                       f"{1 / FAIL_RATE:,.0f} records at {design_loss:.0%} loss",
        "retransmits_below_ms": "a tTimeout below it retransmits records needlessly (at most "
                                "there: the test blocks are full both ways, acknowledgements "
                                "are shorter)",
        "tTransferTimeout_ms": f"{TRANSFER_TIMEOUTS} x tTimeout (wiring.md: a few times tTimeout)",
        "read_period_ms": f"half the slowest delivery ({cycle_ms:.0f} ms, about a poll cycle), "
                          f"{READ_PERIOD_MIN_MS}..{READ_PERIOD_MAX_MS} ms: each side reads at "
                          f"least once per poll (rule C3)",
        "reply_timeout_ms": "10 x the slowest answer of a modem to one request, at least "
                            f"{REPLY_TIMEOUT_MIN_MS} ms (the glue's udiTimeOut / tTimeout per request)",
    }
    return p


def st_snippet(p, header=""):
    """The parameters as ST constants (IEC 61131-3, inside what matiec accepts)."""
    return (f"(* {header} *)\n" if header else "") + (
        "VAR_GLOBAL CONSTANT\n"
        f"    MIP_tTimeout : TIME := T#{p['tTimeout_ms']}ms;\n"
        f"    MIP_uMaxRetries : UINT := {p['uMaxRetries']};\n"
        f"    MIP_tTransferTimeout : TIME := T#{p['tTransferTimeout_ms']}ms;\n"
        f"    MIP_tReadPeriod : TIME := T#{p['read_period_ms']}ms;\n"
        f"    MIP_tReplyTimeout : TIME := T#{p['reply_timeout_ms']}ms;\n"
        "END_VAR\n")


def plcrt_master(p, header=""):
    """The parameters for this project's soft-PLC (runtime_shim/README.md, config): its Modbus
    master's polling period (the read period) and response timeout (the reply timeout); the
    blocks' own parameters are the program's (comments here, the ST constants in st_snippet)."""
    return ((f"# {header}\n" if header else "")
            + f"# the blocks: tTimeout {p['tTimeout_ms']} ms, uMaxRetries {p['uMaxRetries']}, "
              f"tTransferTimeout {p['tTransferTimeout_ms']} ms (docs/commissioning.md)\n"
            + "[master]\n"
            f"polling_period = {p['read_period_ms']}ms\n"
            f"timeout = {p['reply_timeout_ms']}ms\n")


if __name__ == "__main__":
    sys.stdout.write(timeout_table())
