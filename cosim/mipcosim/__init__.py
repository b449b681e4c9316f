"""mipcosim: the example PLC programs (plc/) and the emulated MIP radio in one process, in
lockstep virtual time; plus what the real-mode demo shares with it (register layout, the
logger's expected data, runtime configs, the delivery check)."""
