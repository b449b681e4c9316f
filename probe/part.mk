# probe/: mip-probe, the commissioning tool for a real MIP network (issue 48, docs/commissioning.md).
# Pure Python (pymodbus, pyserial): installs with pip without a C toolchain; the kit's wheel
# carries it too (kit/setup.py). Also the home of the register map of the modems and of the
# sizing rules of the blocks' timeouts (docs/serial.md's table is generated from mipprobe.sizing).
PY_PACKAGES += probe
