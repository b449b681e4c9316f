"""A small network of the kit for the capture tests (test_wireshark_kit_capture.py), importable
by the kit test they run in a pytest of its own."""
from mipcosim import programs as L

RECORDS = [[n, 100 + n, 200 + n] for n in range(1, 8)]


def central_and_peer(net, tmp):
    """The example central (plc/central.st) at the MDP and a note-following peer as station 1,
    sending RECORDS; returns the peer."""
    conf = tmp / "central.conf"
    conf.write_text(L.central_config(502, 1))
    cen = net.plc("central", L.program_sources("central", False), conf, at="mdp")
    peer = net.peer("outstation", at=1, records=RECORDS)
    for i, w in enumerate(L.Params(records=7, payload=3, station=0).words()):
        cen[f"%MW{i}"] = w
    return peer
