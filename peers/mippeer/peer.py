"""One side of a MIP link: which block to write, given what was read and the time.

Still no I/O: `Peer.step(now, read)` takes the result of one read at the read-status register
(status, count, data...) and returns the register block to write, or None.
"""

from .protocol import Receiver, Sender

NEW_READ_DATA = 0x0001


class Peer:
    """Outstation or central, unidirectional (note 2.1) or bidirectional (note 2.2) layout.

    Streams: stream 0 runs outstation -> central, stream 1 central -> outstation. In a block,
    register 0 belongs to stream 0 and (bidirectional only) register 1 to stream 1; payload follows.
    """

    def __init__(self, role, records=None, layout="uni", drive="spontaneous",
                 retransmit_s=2.0, request_s=1.0, static_registers=0):
        if role not in ("outstation", "central"):
            raise ValueError(f"role must be outstation or central, not {role!r}")
        if layout not in ("uni", "bi"):
            raise ValueError(f"layout must be uni or bi, not {layout!r}")
        if drive not in ("polled", "spontaneous"):
            raise ValueError(f"drive must be polled or spontaneous, not {drive!r}")
        self.role, self.layout, self.drive = role, layout, drive
        self.retransmit_s, self.request_s = retransmit_s, request_s
        self.static_registers = static_registers  # 0: dynamic mode (write exactly the block)
        sends = layout == "bi" or role == "outstation"
        receives = layout == "bi" or role == "central"
        self.sender = Sender(records) if sends and records else None
        self.receiver = Receiver() if receives else None
        # Which register of a block carries my outgoing counter and which my acknowledgement.
        mine, theirs = (0, 1) if role == "outstation" else (1, 0)
        self._my_counter, self._my_ack = mine, theirs
        self.header = 2 if layout == "bi" else 1
        self._last_write = None
        self.writes = 0
        self.retransmissions = 0

    @property
    def done(self):
        return self.sender is None or self.sender.done

    def _block(self):
        block = [0] * self.header
        payload = []
        if self.sender is not None and not self.sender.done:
            number, payload = self.sender.current()
            block[self._my_counter if self.layout == "bi" else 0] = number
        if self.receiver is not None:
            block[self._my_ack if self.layout == "bi" else 0] = self.receiver.last_accepted
        block += payload
        if self.static_registers:
            block = (block + [0] * self.static_registers)[: self.static_registers]
        return block

    def step(self, now, read):
        """`read`: registers from the read-status register on (status, count, data...)."""
        status, count, data = read[0], read[1], list(read[2 : 2 + read[1]])
        got_block = bool(status & NEW_READ_DATA) and count >= self.header
        record_arrived = False
        if got_block:
            if self.layout == "uni":
                counter = ack = data[0]
            else:
                counter, ack = data[self._my_ack], data[self._my_counter]
            if self.receiver is not None and (counter != 0 or self.receiver.last_accepted != 0):
                # A record, or the reset record 0 while we still acknowledge something: both
                # must be answered (the reset with acknowledgement 0).
                self.receiver.on_record(counter, data[self.header :])
                record_arrived = True
            if self.sender is not None:
                self.sender.on_ack(ack)
        block = self._block()
        changed = block != self._last_write
        sending = self.sender is not None and not self.sender.done
        since = None if self._last_write is None else now - self._last_write_at
        if self.drive == "polled" and self.role == "outstation":
            # Polled: the outstation only answers the central's requests.
            want = got_block and (sending or record_arrived)
        elif self.drive == "polled":
            # The central's repeated block is the request for the next record.
            want = changed or record_arrived or since is None or since >= self.request_s
        else:
            want = record_arrived or (sending and (
                changed or got_block or since is None or since >= self.retransmit_s))
        if not want:
            return None
        if sending and not changed and not got_block:
            self.retransmissions += 1
        self._last_write, self._last_write_at = block, now
        self.writes += 1
        return block
