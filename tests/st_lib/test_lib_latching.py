"""Latched parameters (st_lib/PROTOCOL.md P26, issue 12): every block samples its parameters at
the rising edge of xExecute / xEnable. Each test changes every parameter of one block in the
middle of a transfer to a value that would visibly break it if it were read live, and checks
that the transfer is unaffected. Virtual time: 10 ms scans, radio poll every 5 scans."""
from pathlib import Path

import pytest

from stlib_sim import FFFF, MS, WAIT, Bi, Uni, pattern


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_latch")


class When:
    """A bench part that runs `action` once, in the first scan in which `cond` holds."""

    def __init__(self, cond, action):
        self.cond, self.action, self.fired = cond, action, False

    def before_scan(self):
        if not self.fired and self.cond():
            self.fired = True
            self.action()


def buffer_pattern(n, seed):
    return [(i * 7 + seed) & 0xFFFF for i in range(n)]


def drop_n(number, n):
    """A fate: the first n telegrams from the outstation carrying `number` are lost for good."""
    left = {"n": n}

    def fate(src, block):
        if src == "O" and block[0] == number and left["n"] > 0:
            left["n"] -= 1
            return "drop"
        return "ok"
    return fate


def change_sender(fb):
    fb["uChunkSize"] = 61
    fb["xBidirectional"] = True
    fb["xCentral"] = True
    fb["xPolled"] = True
    fb["xStatic"] = True
    fb["tTimeout"] = 10 * MS
    fb["uMaxRetries"] = 1
    fb["xRetained"] = True     # live, it would hold every new record: nobody takes a snapshot


def test_buffer_sender_parameters_latched(wd):
    """The issue's case: MIP_BufferSender with 600 registers, uChunkSize 123 -> 61 after record
    2 (plus udiLength and every other parameter): exactly the 600 registers arrive, in records
    of 122, and record 3's two losses are retried as configured at the start (tTimeout 300 ms,
    unlimited retries), not with the new values (10 ms, 1 retry)."""
    u = Uni(wd, buffer=True, timeout_ms=300, fate=drop_n(3, 2))
    u.plc_o["MAIN.bs_seed"] = 3
    u.plc_o["MAIN.bs_fill"] = True
    u.bench.step(1)
    u.plc_o["MAIN.bs_fill"] = False
    u.snd["udiLength"] = 600

    def change():
        change_sender(u.snd)
        u.snd["udiLength"] = 100
    u.bench.parts.insert(0, When(lambda: u.snd["udiRecords"] == 2, change))
    assert u.send(limit=5000) == "done"
    assert u.sink.transfers == [buffer_pattern(600, 3)]
    assert [len(p) for _, p in u.sink.records] == [122] * 4 + [112]
    assert u.snd["udiRetransmissions"] == 2
    assert all(len(w) <= 123 and w[0] in (1, 2, 3, 4, FFFF) for w in u.port_o.writes)


def test_sender_parameters_latched(wd):
    data = pattern(5 * 122 + 17, seed=401)
    u = Uni(wd, data, timeout_ms=300, fate=drop_n(3, 2))
    u.bench.parts.insert(0, When(lambda: u.snd["udiRecords"] == 2, lambda: change_sender(u.snd)))
    u.bench.step(3)
    assert u.send(limit=5000) == "done"
    assert u.sink.transfers == [data]
    assert [n for n, _ in u.sink.records] == [1, 2, 3, 4, 5, FFFF]
    assert [len(p) for _, p in u.sink.records] == [122] * 5 + [17]
    assert u.src.served == [0, 1, 2, 3, 4, 5]
    assert u.snd["udiRetransmissions"] == 2
    # dynamic, unidirectional to the end: counter in register 0, length = counter + payload
    assert [len(w) for w in u.port_o.writes if w[0] == FFFF] == [1 + 17]


def test_receiver_parameters_latched(wd):
    """Mid-transfer the receiver is switched to the bidirectional outstation stream, polled,
    static, tTimeout 10 ms, tTransferTimeout 10 ms, xAckByCaller and xRetained (which would
    hold every acknowledgement forever here: nobody sets xRecordProcessed, nobody takes a
    snapshot); the sender pauses 1 s:
    nothing of this takes effect before xEnable rises again."""
    data = pattern(5 * 122, seed=402)
    u = Uni(wd, data, timeout_ms=300)
    r = u.rcv

    def change():
        r["xBidirectional"] = True
        r["xCentral"] = False
        r["xPolled"] = True
        r["xStatic"] = True
        r["tTimeout"] = 10 * MS
        r["tTransferTimeout"] = 10 * MS
        r["xAckByCaller"] = True
        r["xRetained"] = True   # live, it would hold every acknowledgement: no snapshot comes
        u.src.hold_from = 3
    u.bench.parts.insert(0, When(lambda: r["udiRecords"] == 2, change))
    u.bench.parts.insert(0, When(lambda: u.bench.scans > 300,
                                 lambda: setattr(u.src, "hold_from", None)))
    u.bench.step(3)
    assert u.send(limit=5000) == "done"
    assert u.sink.transfers == [data]
    assert r["udiFailedTransfers"] == 0 and r["udiDuplicates"] == 0
    assert r["udiAcksSent"] <= 1 + 5                      # no 10 ms polling
    # still the unidirectional layout: the echo with acknowledgements 0 and 1, [ack] after them
    assert all(len(w) == (3 if w[0] in (0, 1) else 1) for w in u.port_c.writes)
    # the new values apply from the next rising edge of xEnable
    r["xEnable"] = False
    u.bench.step(2)
    r["xEnable"] = True
    u.bench.step(10)
    n = len(u.port_c.writes)
    assert r["eWaitReason"] == WAIT["MIP_WAIT_SNAPSHOT"] and r["xSnapshotReq"]     # xRetained: acknowledgement 0 waits ...
    r["wSnapshots"] = 1                                    # ... for a snapshot
    u.bench.step(10)
    assert len(u.port_c.writes) == n + 1
    assert len(u.port_c.writes[-1]) == 2                   # bidirectional now: two counters


@pytest.mark.parametrize("side", ["lo", "lc"])
def test_link_parameters_latched(wd, side):
    """MIP_Link: every parameter of one side changed mid-transfer (both directions busy)."""
    d_o, d_c = pattern(4 * 121 + 3, seed=403), pattern(3 * 121 + 50, seed=404)
    bi = Bi(wd, d_o, d_c, timeout_ms=300)
    fb = getattr(bi, side)

    def change():
        fb["xCentral"] = not fb["xCentral"]
        fb["xPolled"] = True
        fb["xStatic"] = True
        fb["uChunkSize"] = 61
        fb["tTimeout"] = 10 * MS
        fb["uMaxRetries"] = 1
        fb["tTransferTimeout"] = 10 * MS
    bi.bench.parts.insert(0, When(lambda: bi.lo["udiRecordsSent"] >= 2
                                  and bi.lc["udiRecordsSent"] >= 2, change))
    bi.bench.step(3)
    assert bi.send_both() == ["done", "done"]
    assert bi.sink_c.transfers == [d_o] and bi.sink_o.transfers == [d_c]
    assert bi.lo["udiFailedTransfers"] == 0 and bi.lc["udiFailedTransfers"] == 0
    assert [len(p) for _, p in bi.sink_c.records] == [121] * 4 + [3]
    assert [len(p) for _, p in bi.sink_o.records] == [121] * 3 + [50]
