"""MIP_Status: read-status bits, count, edge flags, link stalled, MDP field strength and station
status. Virtual time, 10 ms scans."""
from pathlib import Path

import pytest

from stlib_sim import ALL, MS, Fb, build


@pytest.fixture(scope="module")
def wd(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("stlib_status")


@pytest.fixture
def st(wd):
    plc = build(ALL, wd)
    fb = Fb(plc, "st")
    fb["tStallTime"] = 500 * MS
    return fb


def read(fb, status, count=0, scans=1):
    """One completed read (valid for one scan), then `scans - 1` scans without a read."""
    fb.set_read([status, count])
    fb["xReadValid"] = True
    fb.plc.scan()
    fb["xReadValid"] = False
    out = {k: fb[k] for k in ("xNewData", "xWriteWaiting", "xWriteUnconfirmed", "uReadCount",
                               "xNewDataRise", "xWriteWaitingRise", "xUnconfirmedRise",
                               "xWriteSent", "xWriteConfirmed", "xLinkStalled")}
    if scans > 1:
        fb.plc.scan(scans - 1)
    return out


def test_nothing_decoded_before_the_first_read(st):
    st.plc.scan(5)
    assert not st["xValid"] and not st["xNewData"] and st["udiReads"] == 0


def test_bits_and_count(st):
    r = read(st, 0x13, 57)
    assert st["xValid"]
    assert r["xNewData"] and r["xWriteWaiting"] and r["xWriteUnconfirmed"]
    assert r["uReadCount"] == 57
    r = read(st, 0x0C, 3)              # bits 2 and 3 are unused in MIP mode
    assert not (r["xNewData"] or r["xWriteWaiting"] or r["xWriteUnconfirmed"])


def test_edges_last_one_scan_and_follow_a_write_cycle(st):
    read(st, 0x00)
    r = read(st, 0x12)                 # write: waiting + unconfirmed
    assert r["xWriteWaitingRise"] and r["xUnconfirmedRise"] and not r["xWriteSent"]
    st.plc.scan()
    assert not st["xWriteWaitingRise"] and not st["xUnconfirmedRise"]
    assert st["xWriteWaiting"]         # the level holds between reads
    r = read(st, 0x10)                 # sent, not yet confirmed
    assert r["xWriteSent"] and not r["xWriteConfirmed"]
    r = read(st, 0x00)                 # confirmed
    assert r["xWriteConfirmed"] and not r["xWriteSent"]
    r = read(st, 0x01, 10)
    assert r["xNewDataRise"]
    r = read(st, 0x01, 10)             # still set at the next read: no new edge
    assert not r["xNewDataRise"]
    read(st, 0x00)
    r = read(st, 0x01, 10)
    assert r["xNewDataRise"] and st["udiNewData"] == 2 and st["udiReads"] == 8


def test_link_stalled_after_stall_time(st):
    read(st, 0x10, scans=10)           # unconfirmed since now: 100 ms
    assert not st["xLinkStalled"]
    read(st, 0x10, scans=30)           # 400 ms
    assert not st["xLinkStalled"]
    st.plc.scan(11)                    # > 500 ms
    assert st["xLinkStalled"]
    r = read(st, 0x00)
    assert not r["xLinkStalled"]


def test_stall_timer_restarts_when_confirmed_in_between(st):
    read(st, 0x10, scans=40)
    read(st, 0x00)
    read(st, 0x10, scans=40)           # 400 ms since the new unconfirmed block
    assert not st["xLinkStalled"]


def test_field_strength_and_station_status(st):
    st["wFieldStrength"] = 0x4B52      # station hears MDP at -75 dBm, MDP hears station at -82
    st["wStationStatus"] = 0x0005
    st["xStationValid"] = True
    st.plc.scan()
    assert st["iStationHearsMdp"] == -75 and st["iMdpHearsStation"] == -82
    assert st["xStationAnswered"] and st["xStationEverAnswered"]
    assert not st["xStationUnreachable"] and not st["xDownlinkResend"]
    st["wStationStatus"] = 0x000E
    st.plc.scan()
    assert not st["xStationAnswered"] and st["xStationUnreachable"] and st["xDownlinkResend"]
    st["xStationValid"] = False
    st["wStationStatus"] = 0x0001
    st["wFieldStrength"] = 0
    st.plc.scan()                      # no valid read: values held
    assert not st["xStationAnswered"] and st["iStationHearsMdp"] == -75


def failed_read(fb, status):
    """One failed read as the runtime's handshake shows it: error with its status, one scan."""
    fb["xReadError"] = True
    fb["wReadStatus"] = status
    fb.plc.scan()
    fb["xReadError"] = False


def test_a_failed_read_is_a_link_error_with_the_runtimes_reason(st):
    """Reads that keep failing (issue 38: a dead serial line, a refused connection) are never a
    quiet block: xLinkError in the scan of the failure, wLinkError the runtime's status, until a
    read succeeds; the status flags keep the last valid read."""
    read(st, 0x10, 2)
    assert not st["xLinkError"] and st["wLinkError"] == 0 and st["udiReadErrors"] == 0
    failed_read(st, 1110)
    assert st["xLinkError"] and st["wLinkError"] == 1110 and st["udiReadErrors"] == 1
    st.plc.scan(5)                     # no read in between: the error holds
    assert st["xLinkError"] and st["xWriteUnconfirmed"] and st["uReadCount"] == 2
    failed_read(st, 1002)
    assert st["wLinkError"] == 1002 and st["udiReadErrors"] == 2
    read(st, 0x00)
    assert not st["xLinkError"] and st["wLinkError"] == 1002   # the reason is kept
    assert not st["xWriteUnconfirmed"]


def test_a_read_error_held_for_many_scans_counts_once_and_wins_over_a_valid_flag(st):
    """A polled range's error stays TRUE while its polls fail; a program whose xReadValid is
    always TRUE (OpenPLC's cyclic I/O) still sees the error."""
    st["xReadError"] = True
    st["wReadStatus"] = 1111
    st["xReadValid"] = True
    st.plc.scan(10)
    assert st["xLinkError"] and st["wLinkError"] == 1111 and st["udiReadErrors"] == 1
    st["xReadError"] = False
    st.plc.scan()
    assert not st["xLinkError"]
