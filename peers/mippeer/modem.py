"""Register maps of the TRM-810 and MDP-810 in MIP mode, and block I/O through pymodbus."""

import logging
from dataclasses import dataclass

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

READ_SPAN = 125  # read status + count + a whole 123-register chunk in one consistent FC3


@dataclass(frozen=True)
class RegisterMap:
    write_count: int   # number of write registers (read only)
    write_data: int    # first write register: dynamic writes must start here
    read_status: int   # read status, then count, then the read data
    capacity: int = 148


TRM810 = RegisterMap(write_count=2000, write_data=2001, read_status=2198)
MDP810 = RegisterMap(write_count=9, write_data=10, read_status=198)


# pymodbus logs connection failures itself; we report them once, in our own words.
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


class ModemError(RuntimeError):
    pass


class Modem:
    """One modem endpoint. At the MDP-810 the unit id selects the outstation."""

    def __init__(self, host, port, device, unit=1, timeout=2.0):
        self.map = {"trm": TRM810, "mdp": MDP810}[device]
        self.unit = unit
        self.client = ModbusTcpClient(host, port=port, timeout=timeout, retries=0)

    def connect(self):
        if not self.client.connect():
            raise ModemError(f"cannot connect to {self.client.comm_params.host}:{self.client.comm_params.port}")

    def close(self):
        self.client.close()

    def read(self):
        try:
            rr = self.client.read_holding_registers(self.map.read_status, count=READ_SPAN,
                                                    device_id=self.unit)
        except ModbusException as e:  # connection lost, no answer: one line, not a traceback
            raise ModemError(f"read at {self.map.read_status}: {e}") from None
        if rr.isError():
            raise ModemError(f"read at {self.map.read_status}: {rr}")
        return list(rr.registers)

    def write(self, block):
        try:
            wr = self.client.write_registers(self.map.write_data, list(block), device_id=self.unit)
        except ModbusException as e:
            raise ModemError(f"write at {self.map.write_data}: {e}") from None
        if wr.isError():
            raise ModemError(f"write of {len(block)} registers at {self.map.write_data}: {wr}")
