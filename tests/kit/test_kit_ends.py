"""The test kit's ends of the chain (issue 35 item 9): a relay for an integrator's outstation
program, a WinCC OA UNICOS driver stand-in (single, redundant pair, taken down and brought back)
for a central program; what reached the far side, with time stamps and duplicates. In process
(mipkit from kit/), the programs in tests/kit/ends/."""
from pathlib import Path

import pytest

from mipkit import KitError, Net
from mipkit.ends import missing

HERE = Path(__file__).resolve().parent / "ends"
ORIGIN = 1767225600000          # 2026-01-01 00:00:00 UTC
EVENTS = [(0.05, [0x0102, 101, 0x0101, 1]), (0.06, [0x0102, 102, 0x0101, 0]),
          (0.5, [0x0105, 17, 0x0101, 1]), (1.2, [0x0102, 101, 0x0101, 0])]


def lib():
    from mipcosim import programs as L
    return L.lib_sources()


def logged(kp):
    """The relay reader's log: 8 words per entry."""
    return [[kp[f"MAIN.ALOG[{8 * k + j}]"] for j in range(8)] for k in range(kp["MAIN.ULOGN"])]


@pytest.fixture
def net(tmp_path):
    n = Net(tmp_path / "net", 1)
    yield n
    n.close()


def reader(net):
    return net.plc("outstation", lib() + [HERE / "RelayReader.st"], HERE / "relay.conf", at=1)


def test_relay_events_reach_the_outstations_logger_through_a_restart(net):
    kp = reader(net)
    relay = net.relay("relay", kp, "relay", EVENTS, origin_ms=ORIGIN)
    assert net["relay"] is relay
    net.run_for(0.8)
    assert relay.missing(logged(kp)) == relay.expected()[3:]     # the last is still to come
    kp.restart("cold")                     # the relay stays connected to the new instance
    relay.add(2.0, [0x0102, 103, 0x0101, 1])
    net.run_for(2.0)
    # the cold restart lost the log (not the relay's fault): only what came after is in it
    assert relay.missing(logged(kp)) == relay.expected()[:3]
    st = relay.stats()
    assert st["generated"] == 5 and st["acknowledged"] == 5 and st["entries"] == 0
    # a time stamp is origin_ms + the event's virtual ms, most significant word first
    assert relay.expected()[0] == [0x0102, 101, 0x0101, 1, 0, 411, 30426, 43008 + 50]


def test_relay_rate_burst_and_overflow_are_the_relays(net):
    kp = reader(net)
    relay = net.relay("relay", kp, "relay", rate=0.0, burst=(300, 1.0), capacity=50,
                      overflow="drop-new", origin_ms=ORIGIN)
    net.run_for(1.5)
    st = relay.stats()
    assert st["generated"] == 300 and st["dropped"] >= 250 - 64, st   # the log takes 64


def test_relay_bad_input_is_one_line(net):
    kp = reader(net)
    with pytest.raises(KitError, match=r"^outstation: device 'relais' is not in .*relay\.conf "
                                       r"\(it has relay\)$"):
        net.relay("r", kp, "relais")
    with pytest.raises(KitError, match=r"^relay r: overflow 'oldest': use drop-oldest or drop-new$"):
        net.relay("r", kp, "relay", overflow="oldest")
    with pytest.raises(KitError, match=r"^relay r: event \[1, 2, 3\]: four words"):
        net.relay("r", "outstation", "relay", [(0.1, [1, 2, 3])])
    with pytest.raises(KitError, match=r"^relay r: no PLC 'central' on the network"):
        net.relay("r", "central", "relay")
    net.run_for(0.1)
    with pytest.raises(KitError, match=r"before the network runs"):
        net.relay("r2", kp, "relay")


def entry(type_bit, address, cause, value, ts_ms):
    return [type_bit, address, cause, value] + [(ts_ms >> s) & 0xFFFF for s in (48, 32, 16, 0)]


RECORDS = [[entry(0x0101, 10 * r + k, 0x0101, k, ORIGIN + 1000 * r + 10 * k) for k in range(3)]
           for r in range(3)]


def central(net, pair=False, active_b=False):
    kp = net.plc("central", lib() + [HERE / "UnicosCentral.st"], HERE / "unicos.conf", at="mdp")
    kp["MAIN.xPair"], kp["MAIN.xActiveB"] = pair, active_b
    return kp


def hand_over(net, kp, records, within_s=5.0):
    """Each record offered until MIP_UnicosEvents reports it processed; the virtual times."""
    done = []
    for rec in records:
        words = sum(rec, [])
        for i, w in enumerate(words):
            kp[f"MAIN.rec{i}"] = w
        kp["MAIN.uLen"], kp["MAIN.xValid"] = len(words), True
        assert net.run_until(lambda: kp["MAIN.uni.xRecordProcessed"], within_s, step_s=0.05)
        done.append(net.now / 1e9)
        kp["MAIN.xValid"] = False
        net.run_for(0.05)
    return done


def test_unicos_driver_taken_down_and_brought_back(net):
    kp = central(net)
    uni = net.unicos("wincc", kp, "unicos", marker=0xFF80, down=[(0.2, 1.0)])
    net.run_for(0.25)
    done = hand_over(net, kp, RECORDS)
    assert done[0] >= 1.0                 # nothing taken while the driver was down
    events = uni.events("A")
    assert [e["offset"] for e in events] == [0, 1, 2, 10, 11, 12, 20, 21, 22]
    assert all(e["t_s"] >= 1.0 for e in events) and uni.duplicates() == []
    assert events[1]["utc"] == "2026-01-01T00:00:00.010Z" and events[1]["value"] == 0x01010001
    assert missing(sum(RECORDS, []), uni) == []
    assert "driver A: 9 events, 0 duplicates, 0 refused" in uni.report()
    assert missing(sum(RECORDS, []) + [entry(1, 99, 1, 1, ORIGIN)], uni) == [entry(1, 99, 1, 1, ORIGIN)]


def test_unicos_redundant_pair_and_a_restart_that_sends_again(net):
    kp = central(net, pair=True)
    uni = net.unicos("wincc", kp, "unicos", device_b="unicos_b", marker=0xFF80,
                     down_b=[(0.0, 0.6)])
    hand_over(net, kp, RECORDS[:1])
    # A (active) took it at once; B was down: it missed the frame (passive, not waited for)
    assert [e["offset"] for e in uni.events("A")] == [0, 1, 2] and uni.events("B") == []
    net.run_for(0.6)
    kp.restart("cold")                    # both stand-ins follow the new instance
    kp["MAIN.xPair"] = True
    hand_over(net, kp, RECORDS[:2])       # record 0 again: what a restart before the report does
    assert len(uni.duplicates("A")) == 3 and uni.duplicates("B") == []
    assert [e["offset"] for e in uni.events("B")] == [0, 1, 2, 10, 11, 12]
    assert len(uni.unique()) == 6 and missing(sum(RECORDS[:2], []), uni) == []


def test_unicos_bad_input_is_one_line(net):
    kp = central(net)
    with pytest.raises(KitError, match=r"^unicos u: down = \(1, 0\.5\): a pair \[from_s, to_s\]"):
        net.unicos("u", kp, "unicos", down=[(1, 0.5)])
    with pytest.raises(KitError, match=r"^unicos u: down_b without device_b"):
        net.unicos("u", kp, "unicos", down_b=[(0, 1)])
    with pytest.raises(KitError, match=r"^unicos u: marker 70000: a reference number"):
        net.unicos("u", kp, "unicos", marker=70000)
    net.unicos("u", kp, "unicos")
    with pytest.raises(KitError, match=r"^u: already on the network$"):
        net.unicos("u", kp, "unicos_b")
    with pytest.raises(KitError, match=r"^central: device 'unicos' is given to a stand-in already$"):
        net.unicos("u2", kp, "unicos")


def soe_central(net, total):
    kp = net.plc("central", lib() + [HERE / "SoeCentral.st"], HERE / "soe.conf", at="mdp")
    kp["%MW0"] = total
    return kp


def test_scada_polls_the_central_and_takes_every_entry_once(net):
    kp = soe_central(net, 20)
    scada = net.scada("scada", kp, poll_ms=100, down=[(0.5, 1.5)])
    net.run_for(0.45)
    first = len(scada.entries())
    assert 0 < first < 20                   # 3 entries per offer, one offer per poll
    net.run_for(1.0)
    assert len(scada.entries()) == first    # stopped: nothing taken, nothing lost
    assert net.run_until(lambda: kp["MAIN.srv.udiAcked"] == 20, within_s=5)
    rows = scada.entries()
    assert [(r["address"], r["ts_ms"]) for r in rows] == [(k, ORIGIN + k) for k in range(1, 21)]
    assert all(r["t_s"] >= 1.5 for r in rows[first:]) and scada.duplicates() == []
    assert "20 entries, 0 duplicates" in scada.report()
    want = [entry(0x0101, k, 0x0101, k % 2, ORIGIN + k) for k in range(1, 21)]
    assert missing(want, scada) == []


def test_scada_follows_a_restarted_central_and_bad_input_is_one_line(net):
    kp = soe_central(net, 6)
    with pytest.raises(KitError, match=r"^scada s: poll_ms 0: a period in ms, > 0$"):
        net.scada("s", kp, poll_ms=0)
    with pytest.raises(KitError, match=r"^scada s: .*unexpected keyword argument 'period'"):
        net.scada("s", kp, period=1)
    scada = net.scada("s", kp)
    assert net.run_until(lambda: len(scada.entries()) == 6, within_s=3)
    kp.restart("cold")                      # a new slave: the SCADA connects again
    kp["%MW0"] = 3
    assert net.run_until(lambda: len(scada.entries()) == 9, within_s=3)
    # the cold-started server offers entries 1..3 again: the SCADA takes them as new, marked
    assert [r["address"] for r in scada.duplicates()] == [1, 2, 3] and scada.failures >= 1
    other = Net(net.workdir / "other", 1)
    try:
        kr = other.plc("outstation", lib() + [HERE / "RelayReader.st"], HERE / "relay.conf", at=1)
        with pytest.raises(KitError, match=r"^scada s: outstation's config .*relay\.conf has no "
                                           r"\[slave\] section"):
            other.scada("s", kr)
    finally:
        other.close()


PLUGIN_TEST = '''
from pathlib import Path
HERE = Path(r"{here}")

def test_relay_to_log(mip_network, mip_st_lib):
    net = mip_network()
    out = net.plc("outstation", mip_st_lib + [HERE / "RelayReader.st"], HERE / "relay.conf", at=1)
    relay = net.relay("relay", out, "relay", [(0.05, [0x0102, 101, 0x0101, 1])], rate=5.0)
    net.run_for(1)
    log = [[out[f"MAIN.ALOG[{{8 * k + j}}]"] for j in range(8)] for k in range(out["MAIN.ULOGN"])]
    st = relay.stats()
    assert relay.missing(log) == [] and len(log) == st["acknowledged"] and st["generated"] >= 5

def test_wrong_device(mip_network, mip_st_lib):
    net = mip_network()
    out = net.plc("outstation", mip_st_lib + [HERE / "RelayReader.st"], HERE / "relay.conf", at=1)
    net.unicos("wincc", out, "unicos")
'''


def test_the_plugins_network_has_the_ends(tmp_path):
    """Through the pytest plugin (mip_network), as an integrator's test uses them: green, and a
    stand-in given a device the config lacks fails with its one line."""
    import re
    from kit_helpers import kit_pytest
    (tmp_path / "test_user.py").write_text(PLUGIN_TEST.format(here=HERE))
    r = kit_pytest(["test_user.py"], tmp_path, tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 1 and "1 passed" in out and "1 failed" in out, out
    m = re.search(r"_+ test_wrong_device _+\n(.*?)\n(?:-|=)", out, re.S)
    assert m and re.fullmatch(r"outstation: device 'unicos' is not in .*relay\.conf \(it has relay\)",
                              m.group(1).strip()), out


@pytest.mark.slow
def test_the_chains_own_programs_relay_to_scada_over_a_lossy_radio(net):
    """plc/'s chain programs (outstation_soe.st, central_soe.st, their configs unchanged) as an
    integrator's programs in the kit: the relay's events reach the SCADA over the realistic
    radio with 10 % loss each way, the SCADA stopped for 2 s: every event once, in order.
    Slow: a cold build cache builds both programs (tens of seconds); 5 s wall when cached."""
    from mipcosim import chainprograms as C
    lossy = Net(net.workdir / "lossy", 1, radio="realistic", loss_up=0.1, loss_down=0.1, seed=3)
    try:
        out = lossy.plc("outstation", C.program_sources("out"), C.L.PLC_DIR / "outstation_soe.conf",
                        at=1)
        cen = lossy.plc("central", C.program_sources("cen"), C.L.PLC_DIR / "central_soe.conf",
                        at="mdp")
        for kp in (out, cen):
            for i, w in enumerate(C.SoeParams().words()):
                kp[f"%MW{i}"] = w
        events = C.script(40, start_s=0.5, every_s=0.1)
        relay = lossy.relay("relay", out, "relay", events, origin_ms=C.ORIGIN_MS)
        scada = lossy.scada("scada", cen, down=[(2.0, 4.0)])
        assert lossy.run_until(lambda: len(scada.entries()) >= 40, within_s=120, step_s=1)
        lossy.run_for(2)
        assert relay.missing(scada) == [] and scada.duplicates() == []
        assert [tuple(e["regs"]) for e in scada.entries()] == [tuple(e) for e in relay.expected()]
        assert not any(2.0 <= e["t_s"] < 4.0 for e in scada.entries())
    finally:
        lossy.close()
