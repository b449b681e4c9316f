"""The chain example's tests, through the test kit's pytest plugin (fixture mip_network): a
SIPROTEC relay's event recorder read by st/RelayStation.st at station 1, its entries sent over
the radio to st/WinccCentral.st at the MDP-810 and handed to WinCC OA's Modbus driver in UNICOS
mode. The relay and WinCC OA are the kit's stand-ins (net.relay, net.unicos)."""
from datetime import datetime, timedelta, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
STATION = [HERE / "st" / "RelayLog.st", HERE / "st" / "RelayStation.st"]
CENTRAL = [HERE / "st" / "WinccCentral.st"]
ORIGIN_MS = 1767225600000          # the relay's clock at virtual time 0: 2026-01-01 00:00 UTC
# 30 events, one every 0.2 s: [type/bit, address, cause/type, value]
EVENTS = [(0.5 + 0.2 * k, [0x0102, 100 + k, 0x0101, k % 2]) for k in range(30)]


def chain(net, mip_st_lib, events=EVENTS):
    out = net.plc("outstation", mip_st_lib + STATION, HERE / "plcrt" / "relay_station.conf", at=1)
    cen = net.plc("central", mip_st_lib + CENTRAL, HERE / "plcrt" / "wincc_central.conf",
                  at="mdp")
    relay = net.relay("relay", out, "relay", events, origin_ms=ORIGIN_MS)
    wincc = net.unicos("wincc", cen, "wincc", marker=0xFF80, down=[(3.0, 6.0)])  # away 3..6 s
    out["%MW0"] = cen["%MW0"] = 1
    return out, cen, relay, wincc


def short_of(wincc, relay, n):
    """An assertion's message: what WinCC OA took, and the first events it did not."""
    return (f"WinCC OA took {len(wincc.unique())} of {n} events; the first not taken "
            f"(type/bit, address, cause/type, value, time stamp): {relay.missing(wincc)[:2]}")


def utc(t_s):
    """WinCC OA's time stamp of an event the relay recorded at virtual time t_s (10 ms)."""
    t = datetime(1970, 1, 1, tzinfo=timezone.utc) + timedelta(milliseconds=ORIGIN_MS + round(t_s * 1000))
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 10000:02d}0Z"


def test_every_relay_event_reaches_wincc_once_with_its_time_stamp(mip_network, mip_st_lib):
    net = mip_network(radio="realistic", loss_down=0.1, loss_up=0.1, seed=3)
    out, cen, relay, wincc = chain(net, mip_st_lib)
    assert net.run_until(lambda: len(wincc.unique()) == len(EVENTS), within_s=120), \
        short_of(wincc, relay, len(EVENTS))
    net.run_for(2)
    events = wincc.events("A")
    # each event once, in the relay's order, with the relay's time stamp and value
    assert [e["offset"] for e in events] == [w[1] for _, w in EVENTS]
    assert [e["utc"] for e in events] == [utc(t) for t, _ in EVENTS]
    assert [e["value"] for e in events] == [w[0] << 16 | w[3] for _, w in EVENTS]
    away = [e["offset"] for e in events if 3.0 <= e["t_s"] < 6.0]
    assert away == [], f"WinCC OA took events while it was away (3..6 s): offsets {away}"
    assert relay.stats()["entries"] == 0                        # the relay's recorder is empty
    assert out["%MW10"] == len(EVENTS)                          # each stored once at the outstation
    assert out["%MW14"] == 0 and cen["%MW14"] & 1 == 0          # no xError of the MIP blocks


def test_restarts_of_both_plcs_lose_nothing_and_repeat_nothing(mip_network, mip_st_lib):
    net = mip_network(radio="realistic", loss_down=0.1, loss_up=0.1, seed=4)
    out, cen, relay, wincc = chain(net, mip_st_lib)
    net.run_for(2.5)
    out.restart("kill9")                   # back with its last RETAIN snapshot
    net.run_for(2.0)
    cen.restart("warm")                    # SIGTERM: a snapshot at the stop
    assert net.run_until(lambda: len(wincc.unique()) == len(EVENTS), within_s=120), \
        short_of(wincc, relay, len(EVENTS))
    net.run_for(2)
    assert relay.missing(wincc) == []
    assert wincc.duplicates("A") == []
    assert relay.stats()["acknowledged"] == len(EVENTS)


def test_a_burst_larger_than_the_log_waits_in_the_relay(mip_network, mip_st_lib):
    """150 events at once while WinCC OA is away (so nothing is acknowledged over the radio):
    RelayLog holds 64 (st/RelayLog.st uCapacity); while it is full the reader stops
    (MIP_SoeReader xLoggerFull) and the rest wait in the relay's recorder."""
    burst = [(3.2, [0x0103, k, 0x0101, k % 2]) for k in range(150)]
    net = mip_network(radio="fast", seed=1)
    out, cen, relay, wincc = chain(net, mip_st_lib, burst)
    assert net.run_until(lambda: out["RelayStation.lgr.xFull"], within_s=6, step_s=0.05), \
        f"RelayLog not full by 6 s: it stored {out['%MW10']} of the burst's 150"
    assert net.now < 6e9                                         # before WinCC OA is back
    assert relay.stats()["entries"] > 0                         # the rest waits in the relay
    assert net.run_until(lambda: len(wincc.unique()) == len(burst), within_s=120), \
        short_of(wincc, relay, len(burst))
    assert [e["offset"] for e in wincc.events("A")] == list(range(150))
    assert relay.stats()["dropped"] == 0 and relay.stats()["entries"] == 0
