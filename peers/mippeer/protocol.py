"""The chunked logger transfer of the Piciorgros note (section 2), as pure state machines.

No Modbus, no clock: a front feeds in what it read from the modem and writes what these
return. Written from the note and docs/protocol.md, independently of st_lib, so that the two
implementations can be tested against each other.

Counters (register 0 of a block, or registers 0/1 in the bidirectional layout):
  0      nothing accepted yet / nothing to send
  1..    records of one transfer, +1 each
  0xFFFF the last record of a transfer; acknowledged with 0xFFFF
"""

from dataclasses import dataclass, field

LAST = 0xFFFF
MAX_NUMBERED = 0xFFFE  # records 1..65534 can carry their own number; the last one is 65535


class TransferTooLong(ValueError):
    """More records than the counter can number (65534 numbered + the last)."""


def numbers_for(count):
    """Record numbers of a transfer of `count` (>= 2) records: 1, 2, ..., count-1, 65535.

    A transfer always starts with 1; a one-record transfer is sent as [1] followed by an empty
    last record (see Sender), because a lone 65535 right after a completed transfer would look
    like a duplicate of that transfer's last record and be discarded.
    """
    if count < 2:
        raise ValueError("a transfer has at least two numbered records (1 and the last)")
    if count > MAX_NUMBERED + 1:
        raise TransferTooLong(f"{count} records: at most {MAX_NUMBERED + 1} fit one transfer")
    return list(range(1, count)) + [LAST]


class Sender:
    """Sends the records of one transfer after another, each only after the previous was acked."""

    def __init__(self, records):
        records = [list(r) for r in records]
        if len(records) == 1:
            records.append([])  # the empty last record, see numbers_for
        self._numbers = numbers_for(len(records))
        self._records = records
        self.index = 0  # the record being sent
        self.peer_resets = 0  # times the receiver restarted and the transfer began again

    @property
    def done(self):
        return self.index >= len(self._records)

    def current(self):
        """(number, payload) of the record to send, or None when the transfer is complete."""
        if self.done:
            return None
        return self._numbers[self.index], self._records[self.index]

    def on_ack(self, ack):
        """Take the receiver's acknowledgement. Returns True when it moved on to a new record."""
        if self.done:
            return False
        if ack == 0 and self.index > 0:
            # The receiver restarted and forgot the open transfer; it keeps only complete
            # transfers, so what it accepted before is gone too. Report it and send the whole
            # transfer again from record 1 (as st_lib's MIP_ERR_PEER_RESET plus a new execute).
            self.peer_resets += 1
            self.index = 0
            return True
        if ack != self._numbers[self.index]:
            return False
        self.index += 1
        return True


@dataclass
class Receiver:
    """Accepts each record once, mirrors the last accepted number, reports what it cannot deliver."""

    last_accepted: int = 0
    current: list = field(default_factory=list)      # payloads of the transfer in progress
    transfers: list = field(default_factory=list)    # completed transfers: lists of payloads
    aborted: list = field(default_factory=list)      # transfers cut off by a sender restart
    duplicates: int = 0
    unexpected: int = 0

    def expected(self, number):
        if number == 1:
            return True  # a transfer always starts with 1 (a restart of the sender, too)
        if self.last_accepted in (0, LAST):
            return False
        return number == self.last_accepted + 1 or number == LAST

    def on_record(self, number, payload):
        """Take one received record; returns the acknowledgement to send back."""
        if number == 0:
            # Record 0 resets the receiver (the sender starts afresh, e.g. after it failed or
            # restarted): an open transfer is reported aborted; a completed one is forgotten.
            if self.last_accepted not in (0, LAST):
                self.aborted.append(self.current)
                self.current = []
            self.last_accepted = 0
            return 0
        if number == self.last_accepted:
            self.duplicates += 1
            return self.last_accepted
        if not self.expected(number):
            self.unexpected += 1  # ignore it; the sender sees the old ack and goes back
            return self.last_accepted
        if number == 1 and self.last_accepted not in (0, LAST):
            self.aborted.append(self.current)  # sender restarted mid-transfer: report, don't merge
            self.current = []
        elif number == 1:
            self.current = []
        self.current.append(list(payload))
        self.last_accepted = number
        if number == LAST:
            self.transfers.append(self.current)
            self.current = []
        return number
