"""mippeer: an independent implementation of the MIP logger transfer in Python (pymodbus).

protocol.py: the counters as pure state machines; peer.py: one side of a link without I/O;
modem.py: TRM-810 / MDP-810 register maps and block I/O; cli.py: the `mip-peer` command.
"""
