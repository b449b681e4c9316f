# emulator/: the emulated TRM-810 / MDP-810 radio network. A pure C core (libmipemu.a), the
# mip-emulator server over it, C unit and radio-statistics tests, a libFuzzer harness.
EMU_DIR    := emulator
EMU_BUILD  := $(BUILD)/emulator
EMU_CFLAGS := -std=c11 -D_POSIX_C_SOURCE=200809L -O2 -g -Wall -Wextra -Wshadow -I$(EMU_DIR)/include
EMU_CORE_SRC := $(EMU_DIR)/src/mipemu.c $(EMU_DIR)/src/siprotec.c
EMU_HDR    := $(EMU_DIR)/include/mipemu.h $(EMU_DIR)/include/siprotec.h
FUZZ_CC    ?= clang
EMU_FUZZ_RUNS ?= 20000

BUILD_TARGETS += $(EMU_BUILD)/mip-emulator $(EMU_BUILD)/mipemu-sim $(EMU_BUILD)/libmipemu.a
C_TESTS       += emulator-unit emulator-fuzz
QUICK_VARS    += EMU_FUZZ_RUNS=2000
PYTEST_DEPS   += $(EMU_BUILD)/mip-emulator $(EMU_BUILD)/mipemu-sim

# -fPIC: the co-simulation may link the core into a shared object
$(EMU_BUILD)/mipemu.o: $(EMU_DIR)/src/mipemu.c $(EMU_HDR)
	@mkdir -p $(@D)
	$(CC) $(EMU_CFLAGS) -fPIC -c -o $@ $<

# the SIPROTEC event recorder (issue 35): a second device of the same core library
$(EMU_BUILD)/siprotec.o: $(EMU_DIR)/src/siprotec.c $(EMU_HDR)
	@mkdir -p $(@D)
	$(CC) $(EMU_CFLAGS) -fPIC -c -o $@ $<

$(EMU_BUILD)/libmipemu.a: $(EMU_BUILD)/mipemu.o $(EMU_BUILD)/siprotec.o
	rm -f $@ && ar rcs $@ $^

EMU_CLI := $(EMU_DIR)/src/cli_config.c $(EMU_DIR)/src/cli_config.h

$(EMU_BUILD)/mip-emulator: $(EMU_DIR)/src/server.c $(EMU_DIR)/src/rtu.c $(EMU_DIR)/src/rtu.h $(EMU_CLI) $(EMU_BUILD)/libmipemu.a $(EMU_HDR)
	$(CC) $(EMU_CFLAGS) -o $@ $< $(EMU_DIR)/src/rtu.c $(EMU_DIR)/src/cli_config.c $(EMU_BUILD)/libmipemu.a

$(EMU_BUILD)/mipemu-sim: $(EMU_DIR)/src/sim.c $(EMU_CLI) $(EMU_BUILD)/libmipemu.a $(EMU_HDR)
	$(CC) $(EMU_CFLAGS) -o $@ $< $(EMU_DIR)/src/cli_config.c $(EMU_BUILD)/libmipemu.a

$(EMU_BUILD)/test_mipemu: $(EMU_DIR)/tests/test_mipemu.c $(EMU_DIR)/tests/unit.h $(EMU_DIR)/tests/pdu.h $(EMU_BUILD)/libmipemu.a $(EMU_HDR)
	$(CC) $(EMU_CFLAGS) -o $@ $< $(EMU_BUILD)/libmipemu.a -lm

$(EMU_BUILD)/test_siprotec: $(EMU_DIR)/tests/test_siprotec.c $(EMU_DIR)/tests/unit.h $(EMU_DIR)/tests/pdu.h $(EMU_BUILD)/libmipemu.a $(EMU_HDR)
	$(CC) $(EMU_CFLAGS) -o $@ $< $(EMU_BUILD)/libmipemu.a

# the RTU framing (t1.5, t3.5) with explicit times
$(EMU_BUILD)/test_rtu: $(EMU_DIR)/tests/test_rtu.c $(EMU_DIR)/tests/unit.h $(EMU_DIR)/src/rtu.c $(EMU_DIR)/src/rtu.h
	$(CC) $(EMU_CFLAGS) -o $@ $< $(EMU_DIR)/src/rtu.c

$(EMU_BUILD)/fuzz_mipemu: $(EMU_DIR)/fuzz/fuzz_mipemu.c $(EMU_CORE_SRC) $(EMU_HDR)
	@mkdir -p $(@D)
	$(FUZZ_CC) -std=c11 -g -O1 -I$(EMU_DIR)/include -fsanitize=fuzzer,address,undefined \
	  -fno-sanitize-recover=undefined -o $@ $< $(EMU_CORE_SRC)

.PHONY: emulator-unit emulator-fuzz
emulator-unit: $(EMU_BUILD)/test_mipemu $(EMU_BUILD)/test_rtu $(EMU_BUILD)/test_siprotec
	@mkdir -p $(RESULTS)
	$(EMU_BUILD)/test_mipemu --junit $(RESULTS)/emulator-unit.xml
	$(EMU_BUILD)/test_siprotec --junit $(RESULTS)/emulator-unit-siprotec.xml
	$(EMU_BUILD)/test_rtu --junit $(RESULTS)/emulator-unit-rtu.xml

# A short deterministic run (fixed seed and run count: make check 20000, make test 2000) over a
# fresh copy of the seed corpus.
emulator-fuzz: $(EMU_BUILD)/fuzz_mipemu
	@mkdir -p $(RESULTS)
	@rm -rf $(EMU_BUILD)/fuzz-corpus && mkdir -p $(EMU_BUILD)/fuzz-corpus && cp $(EMU_DIR)/fuzz/corpus/* $(EMU_BUILD)/fuzz-corpus/
	@.ci/libfuzzer-run $(EMU_BUILD)/fuzz_mipemu $(EMU_BUILD)/fuzz-corpus $(EMU_FUZZ_RUNS) $(RESULTS)/emulator-fuzz.xml emulator.fuzz
