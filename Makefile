# Top-level build. Each part of the architecture brings its own rules in <part>/part.mk and
# adds itself to the lists below, so parts can be built side by side without touching this file.
#
#   make            build everything (venv with the stc translator, C libraries and programs)
#   make test       build, run every C and Python test suite, JUnit XML into build/test-results/
#   make run        the demo: a logger read out over the emulated radio network
#   make bench      benchmarks (BENCH_QUICK=1 for a short smoke run)

SHELL := /bin/bash
.DEFAULT_GOAL := all

VENV      ?= .venv
VENV_ABS  := $(abspath $(VENV))
PY        := $(VENV_ABS)/bin/python
STC       := $(VENV_ABS)/bin/stc
BUILD     := build
RESULTS   := $(BUILD)/test-results
CC        ?= cc

# Filled in by the parts:
PY_PACKAGES   :=   # directories with a pyproject.toml, installed editable into the venv
BUILD_TARGETS :=   # files or phony targets `make all` builds
C_TESTS       :=   # phony targets that run a C test suite and exit non-zero on failure
PYTEST_DEPS   :=   # what must be built before pytest runs

include $(sort $(wildcard */part.mk))

.PHONY: all venv test c-tests py-tests run bench clean

# everything pytest needs too (PYTEST_DEPS: e.g. the TC6 schema of the docs tests, the bench tools)
all: venv $(BUILD_TARGETS) $(PYTEST_DEPS)

# The venv is remade when the pinned requirements or a package's metadata change.
venv: $(VENV_ABS)/.done
$(VENV_ABS)/.done: requirements.txt $(foreach p,$(PY_PACKAGES),$(p)/pyproject.toml)
	@test -x $(PY) || python3 -m venv $(VENV_ABS)
	@$(PY) -m pip install -q --disable-pip-version-check -r requirements.txt
	@$(if $(strip $(PY_PACKAGES)),$(PY) -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation $(foreach p,$(PY_PACKAGES),-e $(p)),true)
	@touch $@

test: all
	@mkdir -p $(RESULTS)
	@fail=0; for t in $(C_TESTS); do $(MAKE) --no-print-directory $$t || fail=1; done; \
	$(MAKE) --no-print-directory py-tests || fail=1; exit $$fail

py-tests: all $(PYTEST_DEPS)
	@mkdir -p $(RESULTS)
	$(PY) -m pytest -q -p no:cacheprovider --junitxml=$(RESULTS)/pytest.xml tests $(PYTEST_ARGS)

clean:
	rm -rf $(BUILD)
