"""The time a Modbus RTU line takes, and what a serial link adds to the blocks' repeat timeout
tTimeout: one arithmetic for the tables of docs/serial.md (tests/docs/test_docs_serial.py
compares them with this module) and the demo's rule (cli.link_timeout_ms, plc/demo.py).

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


def link_timeout_ms(baud: int, registers: int = 123, frame: str = "8E1",
                    exchanges: int = TIMEOUT_EXCHANGES) -> int:
    """what a serial link at baud adds to tTimeout for records of `registers` registers, ms
    (rounded up to 10 ms)"""
    chars = record_exchange_chars(registers)
    s = exchanges * exchange_s(baud, chars, 0, frame)
    return int(math.ceil(s * 100 - 1e-9)) * 10


def timeout_table(bauds=BAUDS, registers=RECORD_REGISTERS, frame: str = "8E1") -> str:
    """the Markdown table of docs/serial.md: ms to add to tTimeout, per baud and record size"""
    head = "| baud (" + frame + ") | " + " | ".join(f"{r} registers" for r in registers) + " |"
    rule = "|---|" + "---|" * len(registers)
    rows = [f"| {b:,} | " + " | ".join(f"{link_timeout_ms(b, r, frame):,} ms" for r in registers) + " |"
            for b in bauds]
    return "\n".join([head, rule] + rows) + "\n"


if __name__ == "__main__":
    sys.stdout.write(timeout_table())
