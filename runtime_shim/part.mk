# runtime_shim/: plcrt, the soft-PLC runtime (C core library + thin executable, libmodbus),
# and plcharness, the Python package that builds ST programs into it for pytest.
PY_PACKAGES += runtime_shim/harness

RT_BUILD    := $(BUILD)/runtime_shim
RT_SRC      := runtime_shim/src
RT_CORE     := plcrt_core plcrt_image plcrt_config plcrt_master plcrt_transport plcrt_serial_line plcrt_slave plcrt_retain
RT_HEADERS  := runtime_shim/include/plcrt.h $(RT_SRC)/plcrt_internal.h $(RT_SRC)/plcrt_master.h $(RT_SRC)/plcrt_transport.h $(RT_SRC)/plcrt_serial_line.h
RT_CFLAGS   := -std=gnu11 -Wall -Wextra -O2 -g -fPIC -Iruntime_shim/include $(shell pkg-config --cflags libmodbus)
RT_LIBS     := $(shell pkg-config --libs libmodbus) -lpthread -lm

$(RT_BUILD)/%.o: $(RT_SRC)/%.c $(RT_HEADERS)
	@mkdir -p $(@D)
	$(CC) $(RT_CFLAGS) -c $< -o $@

$(RT_BUILD)/libplcrt.a: $(foreach f,$(RT_CORE),$(RT_BUILD)/$(f).o)
	ar rcs $@ $^

BUILD_TARGETS += $(RT_BUILD)/libplcrt.a

# C unit tests: a hand-written program with the matiec ABI (runtime_shim/tests/fakeprog/),
# linked with the core and the per-program glue; a libmodbus test server on 127.0.0.1.
RT_TEST_DIR := runtime_shim/tests
$(RT_BUILD)/test_plcrt: $(RT_TEST_DIR)/test_plcrt.c $(RT_TEST_DIR)/fakeprog/fakeprog.c \
		$(RT_TEST_DIR)/fakeprog/LOCATED_VARIABLES.h $(RT_TEST_DIR)/minitest.h $(RT_TEST_DIR)/testserver.h \
		$(RT_SRC)/plcrt_abi.c $(RT_BUILD)/libplcrt.a $(RT_HEADERS)
	$(CC) $(RT_CFLAGS) -Wno-missing-field-initializers -I$(RT_TEST_DIR)/fakeprog -I$(RT_TEST_DIR) -o $@ \
		$(RT_TEST_DIR)/test_plcrt.c $(RT_TEST_DIR)/fakeprog/fakeprog.c $(RT_SRC)/plcrt_abi.c \
		$(RT_BUILD)/libplcrt.a $(RT_LIBS)

.PHONY: runtime-c-tests
C_TESTS += runtime-c-tests
runtime-c-tests: $(RT_BUILD)/test_plcrt
	@mkdir -p $(RESULTS)
	$(RT_BUILD)/test_plcrt --junit $(RESULTS)/runtime-c-tests.xml

PYTEST_DEPS += $(RT_BUILD)/libplcrt.a

# Benchmark figures (printed): `make bench`, BENCH_QUICK=1 for a short run.
$(RT_BUILD)/bench_plcrt: $(RT_TEST_DIR)/bench_plcrt.c $(RT_TEST_DIR)/fakeprog/fakeprog.c \
		$(RT_TEST_DIR)/testserver.h $(RT_SRC)/plcrt_abi.c $(RT_BUILD)/libplcrt.a $(RT_HEADERS)
	$(CC) $(RT_CFLAGS) -I$(RT_TEST_DIR)/fakeprog -I$(RT_TEST_DIR) -o $@ \
		$(RT_TEST_DIR)/bench_plcrt.c $(RT_TEST_DIR)/fakeprog/fakeprog.c $(RT_SRC)/plcrt_abi.c \
		$(RT_BUILD)/libplcrt.a $(RT_LIBS)

.PHONY: runtime-bench
bench: runtime-bench
runtime-bench: $(RT_BUILD)/bench_plcrt
	$(RT_BUILD)/bench_plcrt

# libFuzzer targets (clang, ASan + UBSan): the slave's request path (a byte stream as one client
# connection) and the config parser. `make test` runs each briefly with a fixed seed from the
# seed corpora in runtime_shim/fuzz/ (RT_FUZZ_RUNS: make check 20000, make test 2000); run one longer by hand, e.g.
#   build/runtime_shim/fuzz_slave -max_total_time=600 build/runtime_shim/fuzz-slave
FUZZ_CC      ?= clang
RT_FUZZ_RUNS ?= 20000
RT_FUZZ_SRC  := $(foreach f,$(RT_CORE),$(RT_SRC)/$(f).c) $(RT_SRC)/plcrt_abi.c $(RT_TEST_DIR)/fakeprog/fakeprog.c
$(RT_BUILD)/fuzz_%: runtime_shim/fuzz/fuzz_%.c $(RT_FUZZ_SRC) $(RT_HEADERS)
	@mkdir -p $(@D)
	$(FUZZ_CC) -std=gnu11 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
	  -Iruntime_shim/include -I$(RT_TEST_DIR)/fakeprog $(shell pkg-config --cflags libmodbus) -o $@ \
	  $< $(RT_FUZZ_SRC) $(RT_LIBS)

.PHONY: runtime-fuzz
C_TESTS += runtime-fuzz
QUICK_VARS += RT_FUZZ_RUNS=2000
runtime-fuzz: $(RT_BUILD)/fuzz_slave $(RT_BUILD)/fuzz_config
	@mkdir -p $(RESULTS)
	@fail=0; for t in slave config; do \
	  rm -rf $(RT_BUILD)/fuzz-ci-$$t && mkdir -p $(RT_BUILD)/fuzz-ci-$$t && \
	  cp runtime_shim/fuzz/corpus_$$t/* $(RT_BUILD)/fuzz-ci-$$t/ && \
	  .ci/libfuzzer-run $(RT_BUILD)/fuzz_$$t $(RT_BUILD)/fuzz-ci-$$t $(RT_FUZZ_RUNS) \
	    $(RESULTS)/runtime-fuzz-$$t.xml runtime.fuzz_$$t || fail=1; done; exit $$fail
