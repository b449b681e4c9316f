# bench/: the benchmarks of issue 8 (docs/benchmarks.md). `make bench` prints the machine and one
# line per figure with its ratio to the target; BENCH_QUICK=1 runs every figure with small
# counts (what CI checks). Build outputs under build/bench/.
BENCH_DIR   := bench
# the mipbench package (bench/mipbench/: one module a figure family), installed editable into the venv
PY_PACKAGES += bench
BENCH_BUILD := $(BUILD)/bench
BENCH_CFLAGS := -std=c11 -D_POSIX_C_SOURCE=200809L -O2 -Wall -Wextra

$(BENCH_BUILD)/mb_client: $(BENCH_DIR)/mb_client.c
	@mkdir -p $(@D)
	$(CC) $(BENCH_CFLAGS) $(shell pkg-config --cflags libmodbus) -o $@ $< $(shell pkg-config --libs libmodbus)

$(BENCH_BUILD)/mb_bare_server: $(BENCH_DIR)/mb_bare_server.c
	@mkdir -p $(@D)
	$(CC) $(BENCH_CFLAGS) $(shell pkg-config --cflags libmodbus) -o $@ $< $(shell pkg-config --libs libmodbus)

$(BENCH_BUILD)/rss_run: $(BENCH_DIR)/rss_run.c
	@mkdir -p $(@D)
	$(CC) $(BENCH_CFLAGS) -D_GNU_SOURCE -o $@ $<

BENCH_BINS := $(BENCH_BUILD)/mb_client $(BENCH_BUILD)/mb_bare_server $(BENCH_BUILD)/rss_run

# The tests in tests/bench/ run `make bench` themselves; they need the programs built.
PYTEST_DEPS += $(BENCH_BINS)

.PHONY: bench-figures
bench: bench-figures
# What the figures run: the emulator, the runtime (plcharness builds programs against it), stc in
# the venv, and the co-simulation library when the cosim part exists.
BENCH_DEPS := venv $(BUILD)/emulator/mip-emulator $(BUILD)/runtime_shim/libplcrt.a \
  $(if $(wildcard cosim/part.mk),$(BUILD)/cosim/libmipcosim.so)
bench-figures: $(BENCH_DEPS) $(BENCH_BINS)
	$(PY) -m mipbench
