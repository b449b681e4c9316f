"""mipbench: the benchmarks of issue 8 (docs/benchmarks.md). `make bench` runs `python -m mipbench`;
one module a figure family (goodput, rtu, scan_cost, emulator, cosim_speed, translator, memory,
readout + kit + chain), what they share in common.py."""
