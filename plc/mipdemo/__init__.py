"""mipdemo: the real-time demos of `make run` (soft-PLCs and mip-emulator over Modbus TCP on
127.0.0.1): the logger's read-out (logger) and the whole chain, relay to SCADA (chain, --chain),
with what both use (common). The top layer: it imports mipcosim, plcharness, mipprobe;
nothing of ours imports it but the tests."""
