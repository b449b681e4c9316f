# plc/: the example ST programs, their generators and the real-time demos (the mip-plc
# distribution, plc/pyproject.toml): mipprograms (stdlib only; mip-glue, OpenPLC's limits and
# plc/gen_programs.py's generator: the co-simulation, the kit and the demos import it) and
# mipdemo (`make run`, plc/demo.py: above mipcosim). plc/*.st are written by hand or generated
# (their first line says so), and committed.
PY_PACKAGES += plc

# The generated ST of plc/ (the logger programs' located images plc/image/*_io.st, central_many's
# with its 8 station instances, the programs still generated whole, the OpenPLC configs): `make`
# rewrites them when what they are made from changes (the description of the image, the
# generators, the types in PLC_Logger.st, whose member order is the %MW block);
# tests/chain/test_chain_programs.py fails when one is stale.
PLC_GENERATED := $(foreach p,outstation central outstation_bidi central_bidi central_many,plc/image/$(p)_io.st)
$(PLC_GENERATED) &: plc/PLC_Logger.st $(wildcard plc/mipprograms/*.py) | $(VENV_ABS)/.done
	$(PY) plc/gen_programs.py > /dev/null
BUILD_TARGETS += $(PLC_GENERATED)
