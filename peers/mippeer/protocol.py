"""The chunked logger transfer of the Piciorgros note, section 2, as pure state machines.

Written from the note alone (and the Modbus facts of the MDP-810 / TRM-810 register maps), NOT
from st_lib: no reset record, no markers, no check values, no quiet waits. It is the peer an
integrator would write from the note, so that interop tests catch our blocks' mistakes.

What the note says (section 2.1, our translation):
  - the first register of a record is the "record counter": a first record always carries 1,
    every further record +1, 0xFFFF (65535) marks the last record of the transfer;
  - 0 marks an undefined state: the central sends it as its "acknowledgement" while it has not
    received any logger data yet;
  - the central always sends back exactly the number of the record it received last; then the
    outstation knows that record was processed and sends the next one; if a record is lost the
    central still sends the old number, "so the outstation sends its record again";
  - the last record is acknowledged with 0xFFFF; after that the next transfer starts with 1.
Section 2.2 runs the same scheme both ways with two counters in front of the payload.

Two readings of the receiver (both are the note, they differ where it is silent):
  strict:  accept only the next number: 1 after 0 or 0xFFFF, N+1 after N, 0xFFFF ("the last
           record") after N or after 0 (a one-record transfer; after 0xFFFF it would be a
           repeat of the last one); anything else is answered with the last acknowledgement.
  lenient: in addition, a record 1 always starts a new transfer (an open one is abandoned).
Senders are the same in both readings, except that a lenient sender takes an acknowledgement 0
in the middle of a transfer as "the receiver has no data of mine" (the note's meaning of 0) and
starts again with record 1; a strict sender just repeats its record.
"""

from dataclasses import dataclass, field

LAST = 0xFFFF
MAX_NUMBERED = 0xFFFE  # records 1..65534 carry their own number; the last one is 65535


class TransferTooLong(ValueError):
    """More records than the counter can number (65534 numbered + the last)."""


def numbers_for(count):
    """Record numbers of a transfer of `count` records: 1, 2, ..., count-1, 0xFFFF.

    A one-record transfer is a lone 0xFFFF: the note marks the last record with 0xFFFF, and a
    record 1 that is never followed by a last record would leave the transfer open forever.
    """
    if count < 1:
        raise ValueError("a transfer has at least one record")
    if count > MAX_NUMBERED + 1:
        raise TransferTooLong(f"{count} records: at most {MAX_NUMBERED + 1} fit one transfer")
    return list(range(1, count)) + [LAST]


class Sender:
    """Sends the records of one transfer, each only after the previous number came back."""

    def __init__(self, records, lenient=False):
        self._records = [list(r) for r in records]
        self._numbers = numbers_for(len(self._records))
        self.lenient = lenient
        self.index = 0       # the record being sent
        self.restarts = 0    # lenient: times an acknowledgement 0 sent us back to record 1

    @property
    def done(self):
        return self.index >= len(self._records)

    def current(self):
        """(number, payload) of the record to send, or None when the transfer is complete."""
        if self.done:
            return None
        return self._numbers[self.index], self._records[self.index]

    def on_ack(self, ack):
        """Take the receiver's acknowledgement. Returns True when it moved to another record."""
        if self.done:
            return False
        if ack == self._numbers[self.index]:
            self.index += 1
            return True
        if self.lenient and ack == 0 and self.index > 0:
            self.index = 0
            self.restarts += 1
            return True
        return False  # the old number (record lost) or anything else: send the record again


@dataclass
class Receiver:
    """Accepts the next record only, mirrors the last accepted number."""

    lenient: bool = False
    last_ack: int = 0
    current: list = field(default_factory=list)      # payloads of the open transfer
    transfers: list = field(default_factory=list)    # completed transfers: lists of payloads
    abandoned: list = field(default_factory=list)    # lenient: open transfers a record 1 ended
    accepted: list = field(default_factory=list)     # every accepted record number, in order
    duplicates: int = 0
    unexpected: int = 0

    def is_next(self, number):
        if self.last_ack in (0, LAST):
            if number == 1:
                return True
            return number == LAST and self.last_ack == 0
        return number == self.last_ack + 1 or number == LAST

    def on_record(self, number, payload):
        """Take one received record; returns the acknowledgement to send back."""
        if number == 0:
            return self.last_ack       # "undefined": the other side has nothing to send
        if self.is_next(number):
            pass
        elif number == self.last_ack:
            self.duplicates += 1       # the same record again (a repeat): the same answer
            return self.last_ack
        elif self.lenient and number == 1:
            self.abandoned.append(self.current)
            self.current = []
        else:
            self.unexpected += 1
            return self.last_ack
        if number == 1 or (number == LAST and self.last_ack in (0, LAST)):
            self.current = []
        self.current.append(list(payload))
        self.accepted.append(number)
        self.last_ack = number
        if number == LAST:
            self.transfers.append(self.current)
            self.current = []
        return number
