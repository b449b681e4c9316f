"""The delivery tap: what a PLC program's own MIP_Receiver instances delivered, record by
record, without glue in the program (issue 39). The co-simulation kernel looks at each
receiver after every scan: when its udiRecords changed it logs wRecordNumber, uRecordLen and
aRecord (the record just delivered, xRecordValid), when its udiTransfers changed a transfer
ended (xTransferEnd). A MIP_Link's receiving side is its inner MIP_Receiver, found the same way.

The receivers are found by type, not by a list the integrator keeps: every instance that has
MIP_Receiver's whole interface as st_lib declares it (report.signatures, the one reader) is
one, also the inner one of a MIP_Link (report.find_blocks keeps the outermost only).
"""
from __future__ import annotations

import ctypes

from .report import signatures

PAYLOAD_MAX = 122      # MIP_T_Payload: 0..121


def receivers(plc) -> list[str]:
    """Instance paths of the MIP_Receiver instances of a plcharness Plc, sorted."""
    want = signatures()["MIP_Receiver"][0]
    members = {}
    for v in plc.variables():
        parent, _, name = v.rpartition(".")
        members.setdefault(parent, set()).add(name)
    return sorted(p for p, names in members.items() if want <= names)


class Receiver:
    """What one receiver instance delivered: `records` (payload lists, in order), `numbers`
    (their record numbers), `transfers` (completed). A warm restart (kill -9 or graceful)
    rolls the instance back to its snapshot: what it delivered after that is forgotten, as
    the program's own store forgets it, and comes again."""

    def __init__(self, path):
        self.path = path
        self.records, self.numbers, self._seqs = [], [], []
        self.transfers = 0
        self._tseq = None

    def _record(self, words):
        number, length = words[0], words[1]
        self.numbers.append(number)
        self.records.append(list(words[2:2 + length]))
        self._seqs.append(words[-1])

    def _transfer(self, words):
        self.transfers += 1
        self._tseq = words[-1]

    def _rolled_back(self, seq, tseq):
        """Keep what the restored instance had delivered (its udiRecords and udiTransfers low
        words are seq and tseq)."""
        while self._seqs and self._seqs[-1] != seq:
            self._seqs.pop()
            self.records.pop()
            self.numbers.pop()
        if self._tseq is not None:
            self.transfers -= (self._tseq - tseq) & 0xFFFF
        self._tseq = tseq


class Taps:
    """The delivery taps of one KitPlc: bound at every start of its program."""

    def __init__(self, net, pid):
        self.net, self.pid = net, pid
        self.by_path: dict[str, Receiver] = {}
        self._slots = {}              # path -> (record slot, transfer slot), kept over restarts
        self._slot_of = {}            # slot -> (Receiver, "record" | "transfer")
        self._keep = []               # ctypes arrays the kernel points into

    def bind(self, plc, restored):
        """Wire the taps to this instance of the program; restored: it came back with a RETAIN
        snapshot (warm / kill -9)."""
        lib, sim = self.net.lib, self.net.sim
        self._keep = []
        for path in receivers(plc):
            rec = self.by_path.setdefault(path, Receiver(path))
            if path not in self._slots:
                self._slots[path] = self.net._tap_slots(2)
            if restored:
                rec._rolled_back(plc[f"{path}.UDIRECORDS"] & 0xFFFF,
                                 plc[f"{path}.UDITRANSFERS"] & 0xFFFF)
            else:
                rec._tseq = None
            s_rec, s_tr = self._slots[path]
            fields = (ctypes.c_void_p * 2)(plc.address(f"{path}.WRECORDNUMBER"),
                                           plc.address(f"{path}.URECORDLEN"))
            self._keep.append(fields)
            self.net._check(lib.mipcosim_tap_fields(
                sim, s_rec, self.pid, plc.address(f"{path}.UDIRECORDS"),
                fields, 2, 1, plc.address(f"{path}.ARECORD"), PAYLOAD_MAX))
            self.net._check(lib.mipcosim_tap_fields(
                sim, s_tr, self.pid, plc.address(f"{path}.UDITRANSFERS"), None, 0, -1, None, 0))
            self._slot_of[s_rec] = (rec, "record")
            self._slot_of[s_tr] = (rec, "transfer")

    def take(self, slot, words):
        """One logged entry of a slot of ours: True if it was ours."""
        hit = self._slot_of.get(slot)
        if hit is None:
            return False
        rec, kind = hit
        if kind == "record":
            rec._record(words)
        else:
            rec._transfer(words)
        return True
