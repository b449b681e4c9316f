# cosim/: lockstep co-simulation (libmipcosim.so + the mipcosim Python package), the chain
# demo (`make run`, plc/demo.py) and the soak (`make soak`).
COSIM_BUILD := $(BUILD)/cosim
PY_PACKAGES += cosim
BUILD_TARGETS += $(COSIM_BUILD)/libmipcosim.so
PYTEST_DEPS += $(COSIM_BUILD)/libmipcosim.so $(BUILD)/emulator/mip-emulator

$(COSIM_BUILD)/libmipcosim.so: cosim/src/mipcosim.c cosim/include/mipcosim.h $(BUILD)/emulator/libmipemu.a $(EMU_HDR)
	@mkdir -p $(@D)
	$(CC) -std=c11 -D_GNU_SOURCE -O2 -g -Wall -Wextra -fPIC -shared -Icosim/include -Iemulator/include \
	  -o $@ cosim/src/mipcosim.c $(BUILD)/emulator/libmipemu.a -lm

.PHONY: run soak
# The demo: emulator + outstation soft-PLC(s) + central soft-PLC over Modbus TCP on 127.0.0.1.
# Options: make run RUN_ARGS="--seed 3 --loss 0.2 --records 50 --stations 2 --realistic"
run: all
	@$(PY) plc/demo.py $(RUN_ARGS)

# >= 10^5 records at 30 % loss with restarts, in co-simulation (not part of `make test`).
soak: all
	@$(PY) -m mipcosim.cli soak $(SOAK_ARGS)

# C unit tests of the library with scripted fake PLCs.
C_TESTS += cosim-unit
$(COSIM_BUILD)/test_mipcosim: cosim/tests/test_mipcosim.c $(COSIM_BUILD)/libmipcosim.so cosim/include/mipcosim.h
	$(CC) -std=c11 -D_GNU_SOURCE -O1 -g -Wall -Wextra -Icosim/include -Iemulator/include -o $@ $< \
	  -L$(COSIM_BUILD) -lmipcosim -Wl,-rpath,$(abspath $(COSIM_BUILD))

.PHONY: cosim-unit
cosim-unit: $(COSIM_BUILD)/test_mipcosim
	@mkdir -p $(RESULTS)
	$(COSIM_BUILD)/test_mipcosim --junit $(RESULTS)/cosim-unit.xml
