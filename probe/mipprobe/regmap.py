"""The register maps of the TRM-810 and the MDP-810 in MIP mode: the one definition in Python
(mip-probe, the Python peer mippeer and the tools import it from here).

Addresses are the note's, PDU addresses counted from 0 (Piciorgros, "SPS-Kopplung über
MODBUS/IP im Zeitschlitzfunk", §3.1 MDP-810, §3.2 TRM-810): the number of write registers, the
write data (up to 148), the read status, the number of registers received, the read data. At
the MDP the register set is per station (note §1.1); which Modbus unit id selects the station is
the project's reading (unit id = station address, docs/protocol.md §4).
"""
from __future__ import annotations

from dataclasses import dataclass

READ_SPAN = 125  # read status + count + a whole 123-register chunk in one consistent FC3

# read status bits (note §3.1.1, §3.2.1)
NEW_DATA, WRITE_WAITING, WRITE_UNCONFIRMED = 0x01, 0x02, 0x10


@dataclass(frozen=True)
class RegisterMap:
    write_count: int   # number of write registers (read only)
    write_data: int    # first write register: dynamic writes must start here
    read_status: int   # read status, then count, then the read data
    capacity: int = 148
    field_strength: int | None = None   # MDP only: register 0 (note §3.1)
    station_status: int | None = None   # MDP only: register 1 (note §3.1; its bits: the note is silent)

    @property
    def read_count(self):
        return self.read_status + 1

    @property
    def read_data(self):
        return self.read_status + 2


TRM810 = RegisterMap(write_count=2000, write_data=2001, read_status=2198)
MDP810 = RegisterMap(write_count=9, write_data=10, read_status=198, field_strength=0,
                     station_status=1)
