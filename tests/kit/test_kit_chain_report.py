"""The kit's report on a broken chain (issue 44): the example project's chain (kit/example:
st/RelayStation.st, st/RelayLog.st, st/WinccCentral.st) broken two ways, through mip-kit and
the pytest plugin. The report's first line names the events that did not reach WinCC OA and
the hop where they stopped (relay -> reader -> logger -> sender -> radio -> receiver ->
hand-over -> control system), not a record of the radio's numbering; a failing test's
artifacts stay under 200 KB, pytest's temporary folders under 5 MB."""
import re

from kit_helpers import REPO, kit_pytest, mipkit_cli

MB = 1_000_000
PAGE = (REPO / "docs" / "test-kit.md").read_text()


def edit(project, old, new, rel="scenarios/chain.toml"):
    """A file of the example project with `old` (there once) replaced by `new`."""
    f = project / rel
    text = f.read_text()
    assert text.count(old) == 1, f"{rel} changed: a new anchor for {old!r}"
    f.write_text(text.replace(old, new))


def ack_on_receipt(project):
    """The central acknowledges a record over the radio as soon as MIP_Receiver delivered it,
    before WinCC OA took its events (xAckByCaller := FALSE)."""
    edit(project, "xAckByCaller := TRUE,", "xAckByCaller := FALSE,", "st/WinccCentral.st")


def drop_address(project):
    """RelayLog says it stored the entries of the addresses ending in 01 (201 of
    scenarios/chain.toml, 101 of tests/test_chain.py) so the reader acknowledges them to the
    relay, but does not keep them. One variant for both: one build."""
    anchor = "IF xEntryValid AND udiStored - udiSent < UINT_TO_UDINT(uCapacity) THEN\n"
    edit(project, anchor, "IF xEntryValid AND WORD_TO_UINT(aEntry[1]) MOD 100 = 1 THEN\n"
                          "  xStored := TRUE;   (* the deliberate bug *)\nELS" + anchor, "st/RelayLog.st")


def size(path):
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def scenario(project, tmp_path):
    r = mipkit_cli([project / "scenarios" / "chain.toml", "--junit", project / "results" / "j.xml",
                    "--workdir", tmp_path / "work"], project)
    out = "\n".join(l for l in r.stdout.splitlines() if not l.startswith("plcrt:"))
    assert r.returncode == 1, out + r.stderr
    return out.splitlines()


BOGUS = ("never delivered by", "the blocks at the fault", "MIP_WAIT_WRITE")


def test_acknowledged_before_wincc_took_them_stops_at_the_hand_over(example, tmp_path):
    ack_on_receipt(example)
    lines = scenario(example, tmp_path)
    # WinCC OA is away from 2 s to 5 s: the events of the records the central took meanwhile
    first = ("mip-kit: fault: 4 of 12 events of relay did not reach wincc, stopped at the "
             "hand-over: address 17 value 0 (3.000 s), address 202 value 1 (3.500 s), address 202 "
             "value 0 (4.000 s) and 1 more; central WINCCCENTRAL.RCV (MIP_Receiver) delivered "
             "them, wincc never took them")
    assert lines[0] == first, "\n".join(lines)
    assert first in PAGE.splitlines(), "docs/test-kit.md shows another line"
    assert lines[1].startswith("FAIL "), "\n".join(lines)
    assert not any(b in l for l in lines for b in BOGUS), "\n".join(lines)
    results = example / "results" / "mip-kit-chain"
    assert (results / "sequence-diagram.svg").is_file()
    assert size(example / "results") < 200_000, f"results/ holds {size(example / 'results')} bytes"


def test_a_log_that_drops_an_address_stops_at_the_logger(example, tmp_path):
    drop_address(example)
    lines = scenario(example, tmp_path)
    assert lines[0] == ("mip-kit: fault: 2 of 12 events of relay did not reach wincc, stopped at "
                        "the logger: address 201 value 0 (0.750 s), address 201 value 1 (2.500 s); "
                        "the reader took them from the relay (12 acknowledged), but no record the "
                        "sender carried holds them and the sender ended idle with nothing in "
                        "flight"), "\n".join(lines)
    assert not any(b in l for l in lines for b in BOGUS), "\n".join(lines)
    shown = "stopped " + lines[0].split(", stopped ", 1)[1]
    assert f"`{shown}`" in " ".join(PAGE.split()), "docs/test-kit.md shows another line"
    assert size(example / "results") < 200_000, f"results/ holds {size(example / 'results')} bytes"


def test_the_plugin_starts_with_the_hop_and_says_what_differs(example, tmp_path):
    """The example's own test (tests/test_chain.py) on the log that drops address 101: the
    report's first line names the logger, the assertion what WinCC OA took; the failing test's
    artifacts stay under 200 KB and pytest's temporary folders under 5 MB."""
    drop_address(example)
    r = kit_pytest(["-k", "test_every_relay_event"], example, tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 1, out
    head = out[out.index("_ test_every_relay_event_reaches_wincc_once_with_its_time_stamp _"):]
    first = head.splitlines()[1]
    assert first.startswith("mip-kit: fault: 1 of 30 events of relay did not reach wincc, stopped "
                            "at the logger: address 101 value 1 (0.700 s); the reader took them"), out
    assert "E       AssertionError: WinCC OA took 29 of 30 events; the first not taken" in out, out
    assert not any(b in head for b in BOGUS), out
    assert "assert False" not in out and "E       assert <not within 120 s: the condition was " \
        "still false at 120.000 s of virtual time>" in out, out
    arts = example / "results" / "mip-kit"
    assert size(arts) < 200_000, f"{arts} holds {size(arts)} bytes"
    assert size(tmp_path / "bt") < 5 * MB, f"pytest's temporary folders keep {size(tmp_path / 'bt')} bytes"


def test_a_radio_that_loses_every_record_stops_at_the_radio(example, tmp_path):
    """The same programs, unbroken, over a radio that loses 99.9 % of the telegrams up: the
    reader took every event, the sender waits for the acknowledgement of its first record."""
    edit(example, "loss_up = 0.1\n", "loss_up = 0.999\n")
    lines = scenario(example, tmp_path)
    assert lines[0].startswith("mip-kit: fault: 12 of 12 events of relay did not reach wincc, "
                               "stopped at the radio: address 200 value 1 (0.500 s), "), lines[0]
    assert lines[0].endswith(" SND ended with eState=MIP_SND_WAIT_ACK eWaitReason=MIP_WAIT_ACK "
                             "wWaitFor=1 eErrorId=MIP_ERR_NONE"), lines[0]


def test_an_outstation_that_never_starts_stops_at_the_relay(example, tmp_path):
    """The outstation left unstarted (%MW0 = 0): its reader never reads, the relay keeps all."""
    edit(example, 'station = 1\nset = { "%MW0" = 1 }', 'station = 1\nset = { "%MW0" = 0 }')
    lines = scenario(example, tmp_path)
    assert lines[0] == ("mip-kit: fault: 12 of 12 events of relay did not reach wincc, stopped at "
                        "the relay: address 200 value 1 (0.500 s), address 201 value 0 (0.750 s), "
                        "address 17 value 1 (1.000 s) and 9 more; its reader never took them (12 "
                        "events (12 scripted), 0 acknowledged, 0 dropped (overflow), 12 still in "
                        "the recorder)"), lines[0]


def test_a_central_restarted_cold_stops_at_the_receiver(example, tmp_path):
    """The central restarted cold at 5.3 s (its %MW0 start word gone: MIP_Receiver disabled):
    the radio still delivers the sender's telegrams, no receiver takes them."""
    edit(example, 'at_s = 4\nrestart = "outstation"\nmode = "kill9"',
         'at_s = 5.3\nrestart = "central"\nmode = "cold"')
    lines = scenario(example, tmp_path)
    assert re.fullmatch(r"mip-kit: fault: 7 of 12 events of relay did not reach wincc, stopped at "
                        r"the receiver: address 17 value 0 \(3\.000 s\), .*; the reader took them "
                        r"from the relay, the radio delivered (\d+) of the sender's \1 telegrams up "
                        r"in the last 10 s, no receiver delivered them; SND ended with .*, RCV with "
                        r"eState=MIP_RCV_DISABLED .*", lines[0]), lines[0]
