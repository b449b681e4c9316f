# Top-level build. Each part of the architecture brings its own rules in <part>/part.mk and
# adds itself to the lists below, so parts can be built side by side without touching this file.
#
#   make            build everything (venv with the stc translator, C libraries and programs)
#   make test       the quick tier: every suite, its slow variants left out (minutes)
#   make check      the full tier: every test but the large tier's, the model's proofs but the
#                   largest, full fuzz budgets (<= 25 min on 2 cores)
#   make check-large the large tier: the largest model proofs (model/configs.py LARGE) and the
#                   longest pytest tests (tests/conftest.py LARGE_TIER); CI runs make check, then this
#   make run        the demo: a logger read out over the emulated radio network
#   make view       the link live in the browser (mip-view; VIEW_ARGS, docs/view.md)
#   make bench      benchmarks (BENCH_QUICK=1 for a short smoke run)
#
# Both tiers run their suites side by side (make -j, JOBS; pytest-xdist inside the pytest
# suites), each suite's output into build/test-results/<suite>.log with its JUnit XML, and end
# with one table: suite, tests, passed, failed, skipped, seconds (build/test-results/timing.txt).

SHELL := /bin/bash
.DEFAULT_GOAL := all

VENV      ?= .venv
VENV_ABS  := $(abspath $(VENV))
PY        := $(VENV_ABS)/bin/python
STC       := $(VENV_ABS)/bin/stc
BUILD     := build
RESULTS   := $(BUILD)/test-results
CC        ?= cc

# Python keeps the compiled form of our modules under build/pycache (not beside the sources).
# With PYTHONDONTWRITEBYTECODE set, as on our CI machine, each of the test runs' thousands of
# Python processes compiled our packages again (0.16 s of CPU a start) and each pytest worker
# rewrote the asserts of every test module again (6 s of CPU each)
unexport PYTHONDONTWRITEBYTECODE
export PYTHONPYCACHEPREFIX := $(abspath $(BUILD))/pycache

JOBS      ?= $(shell nproc 2>/dev/null || echo 2)
# pytest-xdist workers of each pytest suite, and what the suites leave out (make test sets it
# to "not slow"; make check runs everything): tests/conftest.py says what is slow and why
PYTEST_N    ?= auto
# make test's py-tests run two workers a core: its quick tests wait on real time (sockets,
# timers, processes starting) for much of theirs, and two workers kept 1.3 of 2 cores busy
# (make test on 2 cores, quiet: 329 s with 2 workers, 290 s with 3, 266 s with 4). make check
# keeps PYTEST_N: its suites already share the cores for 20 minutes
QUICK_PY_N  ?= $(shell echo $$(( 2 * $(JOBS) )))
PYTEST_MARK ?=
PYTEST_RUN := $(PY) -m pytest -q -p no:cacheprovider -n $(PYTEST_N) --dist loadgroup --durations=15
PYTEST    := $(PYTEST_RUN) $(if $(strip $(PYTEST_MARK)),-m "$(PYTEST_MARK)")
SUITE     := python3 .ci/suite.py

# Filled in by the parts:
PY_PACKAGES   :=   # directories with a pyproject.toml, installed editable into the venv
BUILD_TARGETS :=   # files or phony targets `make all` builds
C_TESTS       :=   # phony targets that run a test suite and exit non-zero on failure; each
                   # writes its JUnit XML to $(RESULTS)/<target>.xml or <target>-*.xml
PYTEST_DEPS   :=   # what must be built before pytest runs
QUICK_VARS    :=   # what make test passes to the suites (smaller budgets: fuzz runs, model set)
LARGE_SUITES  :=   # phony targets make check leaves to make check-large (CI runs both)

include $(sort $(wildcard */part.mk))

.PHONY: all venv test check check-large suites c-tests py-tests run bench clean

# everything pytest needs too (PYTEST_DEPS: e.g. the TC6 schema of the docs tests, the bench tools)
all: venv $(BUILD_TARGETS) $(PYTEST_DEPS)

# The venv is remade when the pinned requirements or a package's metadata change.
venv: $(VENV_ABS)/.done
$(VENV_ABS)/.done: requirements.txt $(foreach p,$(PY_PACKAGES),$(p)/pyproject.toml)
	@test -x $(PY) || python3 -m venv $(VENV_ABS)
	@$(PY) -m pip install -q --disable-pip-version-check -r requirements.txt
	@$(if $(strip $(PY_PACKAGES)),$(PY) -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation $(foreach p,$(PY_PACKAGES),-e $(p)),true)
	@# the kit (mipkit) on the venv's path as an editable install puts it, but without its
	@# pytest11 entry point, which would load the kit's plugin into every pytest run here
	@echo "$(abspath kit)" > "$$($(PY) -c 'import sysconfig; print(sysconfig.get_path("purelib"))')/mip-logger-kit-source.pth"
	@touch $@

# The suites, longest first (make starts them in this order): make -k runs every one even
# when one fails; the summary then fails the run.
LONG_SUITES := model-check semantics-iec-tests
SUITES = py-tests $(filter $(LONG_SUITES),$(C_TESTS)) $(filter-out $(LONG_SUITES),$(C_TESTS))

test: all
	@$(SUITE) start --results $(RESULTS)
	@$(MAKE) --no-print-directory -k -j$(JOBS) suites PYTEST_MARK="not slow" PY_TESTS_N=$(QUICK_PY_N) $(QUICK_VARS); \
	$(SUITE) summary --results $(RESULTS) --title "make test" $(SUITES)

check: all
	@$(SUITE) start --results $(RESULTS)
	@$(MAKE) --no-print-directory -k -j$(JOBS) suites PYTEST_MARK="not large"; \
	$(SUITE) summary --results $(RESULTS) --title "make check" $(SUITES)

# Too long for make check's 25 minutes, not for CI: .ci/run runs this after make check.
# Its results and timing table go to $(RESULTS)-large, beside make check's.
check-large: all
	@$(SUITE) start --results $(RESULTS)-large
	@$(MAKE) --no-print-directory -k -j$(JOBS) $(addprefix suite/,$(LARGE_SUITES)) RESULTS=$(RESULTS)-large; \
	$(SUITE) summary --results $(RESULTS)-large --title "make check-large" $(LARGE_SUITES)

suites: $(addprefix suite/,$(SUITES))
suite/%:
	+@$(SUITE) run --results $(RESULTS) $* -- $(MAKE) --no-print-directory $*

py-tests: all $(PYTEST_DEPS)
	@mkdir -p $(RESULTS)
	$(PYTEST) $(if $(PY_TESTS_N),-n $(PY_TESTS_N)) --junitxml=$(RESULTS)/py-tests.xml tests $(PYTEST_ARGS)

# make check-large's pytest suite: the tests tests/conftest.py LARGE_TIER names (-m large)
LARGE_SUITES += py-tests-large
.PHONY: py-tests-large
py-tests-large: all $(PYTEST_DEPS)
	@mkdir -p $(RESULTS)
	$(PYTEST_RUN) -m large --junitxml=$(RESULTS)/py-tests-large.xml tests $(PYTEST_ARGS)

clean:
	rm -rf $(BUILD)
