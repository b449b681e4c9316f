"""pymodbus 3 TCP server with 500 holding registers, the Python peer of the throughput figure.

    python -m mipbench.pymodbus_server PORT

Prints "listening port=N" once the socket accepts, serves until SIGTERM / SIGINT."""
import asyncio
import logging
import signal
import sys

from pymodbus.datastore import ModbusDeviceContext, ModbusSequentialDataBlock, ModbusServerContext
from pymodbus.server import ModbusTcpServer


async def main(port):
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    block = ModbusSequentialDataBlock(1, list(range(500)))  # the device context adds 1
    ctx = ModbusServerContext(devices=ModbusDeviceContext(hr=block), single=True)
    server = ModbusTcpServer(ctx, address=("127.0.0.1", port))
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, lambda: asyncio.ensure_future(server.shutdown()))
    task = asyncio.create_task(server.serve_forever())
    for _ in range(500):
        await asyncio.sleep(0.01)
        if server.transport is not None:
            break
    print(f"listening port={port}", flush=True)
    await task


if __name__ == "__main__":
    try:
        port = int(sys.argv[1]) if len(sys.argv) == 2 else -1
    except ValueError:
        port = -1
    if not 1 <= port <= 65535:
        sys.exit("usage: python -m mipbench.pymodbus_server PORT (1..65535)")
    try:
        asyncio.run(main(port))
    except KeyboardInterrupt:
        pass
