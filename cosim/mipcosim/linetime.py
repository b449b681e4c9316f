"""The time a Modbus RTU line takes, and what a serial link adds to the blocks' repeat timeout
tTimeout: one arithmetic for the tables of docs/serial.md (tests/docs/test_docs_serial.py
compares them with this module) and the demo's rule (cli.link_timeout_ms, plc/demo.py). The
same rule sizes what the chain's hand-over to a polling SCADA adds (handover_timeout_ms,
plc/demo_chain.py): the steps a round trip waits for in series, times their duration.

    python -m mipcosim.linetime      # prints the tTimeout table of docs/serial.md

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


if __name__ == "__main__":
    sys.stdout.write(timeout_table())
