"""The emulator's relay (C core, mip-emulator --relay) against the independent relay written from
the manuals (peers/mippeer/siprotec.py): the same master handshake, the same scripted events, the
same answers register for register (issue 35, item 7)."""
import pytest

from mippeer.siprotec import EventRecorder, RelayConfig, RelayServer as PeerServer, load_script
from relay_support import ORIGIN_MS, Master, RelayServer, exc, write_script

EVENTS = [(k / 1000, 0x0100 | k, 200 + k, 0x0201 if k % 2 else 0x0102, 1000 * k) for k in range(1, 10)]


def run_master(port, base, scenario):
    """scenario(master) against the relay at port, the master closed after it."""
    m = Master(port, base=base)
    try:
        return scenario(m)
    finally:
        m.close()


def scenario(m):
    """A master that does everything once: reads, repeats, partial and wrong acknowledgements,
    write to read-only registers, FC16 acknowledgement, reset list. -> what it saw."""
    seen = []
    _, seq, _, raw = m.read()
    seen += [("read", raw), ("read again", m.read()[3])]
    seen.append(("wrong seq", m.ack(seq + 1, 1)))
    seen.append(("too many", m.ack(seq, 4)))
    seen.append(("partial", m.ack(seq, 1)))
    _, seq, _, raw = m.read()
    seen.append(("read", raw))
    seen.append(("write count", exc(m.c.write_register(m.base, 7))))
    seen.append(("write block", exc(m.c.write_register(m.base + 9, 7))))
    seen.append(("outside", exc(m.c.write_register(m.base + 26, 7))))
    seen.append(("fc4", exc(m.c.read_input_registers(m.base, count=2))))
    seen.append(("fc16 ack", exc(m.c.write_registers(m.base + 1, [seq | 3 << 8]))))
    _, seq, _, raw = m.read()
    seen.append(("read", raw))
    seen.append(("ack repeated", [m.ack(seq, 3), m.ack(seq, 3)]))
    seen.append(("read", m.read()[3]))
    seen.append(("count only", m.count()))
    _, seq, _, raw = m.read()
    seen.append(("reset with ack", m.ack(seq, 0, reset=True)))
    seen.append(("read", m.read()[3]))
    seen.append(("reset alone", m.ack(0, 0, reset=True)))
    seen.append(("read", m.read()[3]))
    return seen


@pytest.mark.parametrize("opts", ["", "cap=5", "cap=5,overflow=drop-new", "bad-ack=ignore,base=0",
                                  "seq-bits=2"])
def test_emulator_and_independent_relay_answer_alike(tmp_path, opts):
    script = write_script(tmp_path / "events.txt", EVENTS)
    kv = dict(o.split("=") for o in opts.split(",") if o)
    base = int(kv.get("base", 600))

    emu = RelayServer(f"script={script}" + ("," + opts if opts else ""))
    try:
        emu.sleep_past(max(e[0] for e in EVENTS))
        ours = run_master(emu.port, base, scenario)
    finally:
        assert emu.stop() == 0

    rec = EventRecorder(RelayConfig(base=base, capacity=int(kv.get("cap", 200)),
                                    overflow=kv.get("overflow", "drop-oldest"),
                                    seq_bits=int(kv.get("seq-bits", 8)),
                                    bad_ack=kv.get("bad-ack", "exc03"), origin_ms=ORIGIN_MS))
    for t, w in load_script(script):
        rec.add(t, w)
    rec.advance(1.0)
    peer = PeerServer(rec).start()
    try:
        theirs = run_master(peer.port, base, scenario)
    finally:
        peer.shutdown()
        peer.server_close()

    assert ours[0][1][0] > 0, "the scenario must see entries"
    for a, b in zip(ours, theirs):
        assert a == b
    assert len(ours) == len(theirs)


def test_both_relays_keep_read_blocks_while_events_arrive(tmp_path):
    """In real time: two events, a read, three more events, then the handshake goes on. Both
    relays must keep what the master read until it acknowledges, and agree on every answer."""
    import time
    events = [(0.001, 0x0101, 1, 0x0101, 1), (0.002, 0x0101, 2, 0x0101, 2)] + \
             [(0.8, 0x0101, 3 + k, 0x0101, 3 + k) for k in range(3)]
    script = write_script(tmp_path / "events.txt", events)

    rec = EventRecorder(RelayConfig(origin_ms=ORIGIN_MS))
    for t, w in load_script(script):
        rec.add(t, w)
    t0 = time.monotonic()
    peer = PeerServer(rec, clock=lambda: time.monotonic() - t0).start()
    emu = RelayServer(f"script={script}")
    masters = [Master(emu.port), Master(peer.port)]
    try:
        emu.sleep_past(0.002, margin=0.1)
        seen = [[] for _ in masters]
        for m, out in zip(masters, seen):
            out.append(m.read()[3])
        emu.sleep_past(0.8)
        for m, out in zip(masters, seen):
            out.append(m.read()[3])
            seq = out[-1][1] & 0xFF
            out.append(m.ack(seq, 2))
            out.append(m.read()[3])
            out.append(m.ack(out[-1][1] & 0xFF, 3))
            out.append(m.read()[3])
        assert seen[0][0][1] == 1 | 2 << 8 and seen[0][1][0] == 5 and seen[0][1][1:] == seen[0][0][1:]
        assert seen[0] == seen[1]
    finally:
        for m in masters:
            m.close()
        peer.shutdown()
        peer.server_close()
        assert emu.stop() == 0
