"""One side of a MIP link: which block to write, given what was read and the time.

Still no I/O: `Peer.step(now, read)` takes the result of one read at the read-status register
(status, count, data...) and returns the register block to write, or None.

Layouts (note 2.1 / 2.2):
  uni  outstation writes [record counter, payload...]; central writes [acknowledgement].
  bi   outstation writes [its record counter, its ack of the central's records, payload...];
       central writes [its ack of the outstation's records, its record counter, payload...].
A side with nothing (more) to send writes counter 0 ("undefined") and no payload.

MIP modes: dynamic writes exactly the block (FC16 at the first write register); static writes
the configured number of registers every time (the block, padded with zeros).

Drives: spontaneous: the sender writes a record at once and repeats it after `retransmit_s`
without its number coming back; polled: the central writes its block every `request_s` (its
acknowledgement is the request) and the outstation writes only in answer to a received block.
A receiver always answers a received record with its (possibly unchanged) acknowledgement.
"""

from .protocol import Receiver, Sender

NEW_READ_DATA = 0x0001


class Peer:
    def __init__(self, role, records=None, layout="uni", drive="spontaneous", lenient=False,
                 retransmit_s=2.0, request_s=1.0, static_registers=0):
        if role not in ("outstation", "central"):
            raise ValueError(f"role must be outstation or central, not {role!r}")
        if layout not in ("uni", "bi"):
            raise ValueError(f"layout must be uni or bi, not {layout!r}")
        if drive not in ("polled", "spontaneous"):
            raise ValueError(f"drive must be polled or spontaneous, not {drive!r}")
        self.role, self.layout, self.drive = role, layout, drive
        self.retransmit_s, self.request_s = retransmit_s, request_s
        self.static_registers = static_registers  # 0: dynamic mode
        self.header = 2 if layout == "bi" else 1
        sends = layout == "bi" or role == "outstation"
        receives = layout == "bi" or role == "central"
        if records and not sends:
            raise ValueError("the central sends records only in the bidirectional layout (--layout bi)")
        if static_registers:
            longest = max((len(r) for r in records or []), default=0)
            if self.header + longest > static_registers:
                raise ValueError(f"a record of {longest} registers does not fit "
                                 f"{static_registers} static registers with {self.header} counter(s)")
        self.sender = Sender(records, lenient) if sends and records else None
        self.receiver = Receiver(lenient=lenient) if receives else None
        # register of a block holding my record counter / my acknowledgement (bi layout)
        self._counter_at, self._ack_at = (0, 1) if role == "outstation" else (1, 0)
        self._last_write = None
        self._last_write_at = None
        self.writes = 0
        self.repeats = 0

    @property
    def done(self):
        return self.sender is None or self.sender.done

    def block(self):
        block = [0] * self.header
        payload = []
        if self.sender is not None and not self.sender.done:
            number, payload = self.sender.current()
            block[self._counter_at if self.layout == "bi" else 0] = number
        if self.receiver is not None:
            block[self._ack_at if self.layout == "bi" else 0] = self.receiver.last_ack
        block += payload
        if self.static_registers:
            block = (block + [0] * self.static_registers)[: self.static_registers]
        return block

    def step(self, now, read):
        """`read`: registers from the read-status register on (status, count, data...)."""
        status, count = read[0], read[1]
        data = list(read[2 : 2 + count])
        got = bool(status & NEW_READ_DATA) and count >= self.header
        record_arrived = False
        if got:
            if self.layout == "uni":
                number = ack = data[0]
            else:
                number, ack = data[self._ack_at], data[self._counter_at]
            if self.receiver is not None and number != 0:
                self.receiver.on_record(number, data[self.header :])
                record_arrived = True
            if self.sender is not None:
                self.sender.on_ack(ack)
        block = self.block()
        sending = self.sender is not None and not self.sender.done
        since = None if self._last_write_at is None else now - self._last_write_at
        if self.drive == "polled" and self.role == "outstation":
            want = got and (sending or record_arrived)
        elif self.drive == "polled":
            want = (since is None or record_arrived or block != self._last_write
                    or since >= self.request_s)
        else:
            want = (since is None or record_arrived or block != self._last_write
                    or (sending and since >= self.retransmit_s))
        if not want:
            return None
        if block == self._last_write:
            self.repeats += 1
        self._last_write, self._last_write_at = block, now
        self.writes += 1
        return block
