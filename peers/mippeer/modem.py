"""Register maps of the TRM-810 and MDP-810 in MIP mode (from mipprobe.regmap), and block I/O through pymodbus.

Transports: Modbus TCP to the modem (pymodbus's ModbusTcpClient; the command), or a function that
takes one request ADU and returns the response ADU (`Modem.in_process`; e.g. a simulation that
hands it to an emulated modem at its virtual time). Either way pymodbus's own client builds and
checks the frames (MBAP header + PDU); only the byte pipe differs, so the peer makes the same
requests in a simulation as over TCP.
"""

import logging

from pymodbus.client import ModbusTcpClient
from pymodbus.client.base import ModbusBaseSyncClient
from pymodbus.exceptions import ModbusException
from pymodbus.framer import FramerType
from pymodbus.transport import CommParams, CommType

# the register maps: one definition, in mip-probe's package (pure Python, pymodbus only)
from mipprobe.regmap import MDP810, READ_SPAN, TRM810, RegisterMap  # noqa: F401


# pymodbus logs connection failures itself; we report them once, in our own words.
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


class ModemError(RuntimeError):
    pass


class AduClient(ModbusBaseSyncClient):
    """pymodbus's synchronous client with a function for its byte pipe: each request frame
    (MBAP header + PDU, exactly what ModbusTcpClient writes to its socket) goes to
    transact(adu), which returns the response frame, or None for no answer (pymodbus then reports
    that no response came, as after a TCP timeout). No socket, no waiting."""

    def __init__(self, transact, name="in-process"):
        params = CommParams(comm_type=CommType.TCP, comm_name=name, host=name, port=0,
                            timeout_connect=0.0)
        super().__init__(FramerType.SOCKET, 0, params, None, None, None)
        self._transact = transact
        self._response = b""

    def connect(self):
        return True

    def close(self):
        self._response = b""

    def send(self, request, addr=None):
        self._response = self._transact(bytes(request)) or b""
        return len(request)

    def recv(self, size):
        data, self._response = self._response, b""
        return data


class Modem:
    """One modem endpoint. At the MDP-810 the unit id selects the outstation. `client`: a
    pymodbus synchronous client to use instead of Modbus TCP to host:port."""

    def __init__(self, host, port, device, unit=1, timeout=2.0, client=None):
        self.map = {"trm": TRM810, "mdp": MDP810}[device]
        self.unit = unit
        self.client = client if client is not None else \
            ModbusTcpClient(host, port=port, timeout=timeout, retries=0)

    @classmethod
    def in_process(cls, transact, device, unit=1):
        """The modem behind a function: transact(request ADU) -> response ADU or None."""
        return cls(None, None, device, unit, client=AduClient(transact))

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
