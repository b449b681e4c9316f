# plc/: the example ST programs, their generators and the real-time demos (the mip-plc
# distribution, plc/pyproject.toml): mipprograms (mip-glue, OpenPLC's limits and
# plc/gen_programs.py's generator: the co-simulation, the kit and the demos import it) and
# mipdemo (`make run`, plc/demo.py: above mipcosim). The logic of every program in plc/ is
# written by hand; only the located images plc/image/*_io.st are generated (their first line
# says so), and committed.
PY_PACKAGES += plc

# The generated ST of plc/ (the located images plc/image/*_io.st of the logger and chain
# programs, central_many's with its 8 station instances, the OpenPLC configs): `make` rewrites
# them when what they are made from changes (the descriptions of the image, the generators, the
# types in PLC_Logger.st and PLC_SoeChain.st, whose member order is the %MW block);
# tests/chain/test_chain_programs.py fails when one is stale.
PLC_GENERATED := $(foreach p,outstation central outstation_bidi central_bidi central_many \
                   outstation_soe central_soe central_push,plc/image/$(p)_io.st)
$(PLC_GENERATED) &: plc/PLC_Logger.st plc/PLC_SoeChain.st $(wildcard plc/mipprograms/*.py) | $(VENV_ABS)/.done
	$(PY) plc/gen_programs.py > /dev/null
BUILD_TARGETS += $(PLC_GENERATED)
