# tests/support: the package miptest, the helpers that tests in more than one folder use
# (issue 45: installed like every part, never added to the import path by a test)
PY_PACKAGES += tests/support

# tests/: the ST library and the example programs once more with stc --semantics=iec (issue 13).
# The default pass (py-tests) builds them with matiec's values; this pass with IEC 61131-3's.
# A test whose outcome differs between the two passes is a portability bug in our ST.
# make test runs its quick tier (PYTEST_MARK; st_lib only), make check all of it.
C_TESTS += semantics-iec-tests
IEC_TEST_PATHS ?= tests/st_lib tests/chain/test_chain_cosim.py
QUICK_VARS += IEC_TEST_PATHS=tests/st_lib

.PHONY: semantics-iec-tests
semantics-iec-tests: all
	@mkdir -p $(RESULTS)
	PLCRT_SEMANTICS=iec $(PYTEST) --junitxml=$(RESULTS)/semantics-iec-tests.xml \
	  $(IEC_TEST_PATHS)

# tests/: the st_lib behaviour tests once more on the TIA SCL that stc.scl_out generates from
# st_lib (issue 36): under PLCRT_STLIB_DIALECT=scl the bench (tests/st_lib/stlib_sim.py) builds
# the library from the generated .scl with stc --dialect=scl, so the SCL is checked by running
# it. make test runs a quick subset (about 26 s of CPU with a cold build cache: the core
# protocol, the modes, the status decoder, the PLCopen latching, window 2, warm restarts),
# make check every module that builds through the bench.
C_TESTS += scl-tests
# The modules whose PLCs the bench builds (its Uni, Bi, build or lib_sources): the others build
# their own way and would only run as ST once more. A new bench builds through
# stlib_sim.lib_sources / lib_type (as soe_bench and unicos_bench do) to be run here on the SCL too.
SCL_TEST_PATHS ?= $(filter-out tests/st_lib/test_lib_scl_status.py,$(shell grep -lE \
  'from stlib_sim import .*\b(Uni|Bi|build|lib_sources)\b|from (soe|unicos)_bench import' \
  tests/st_lib/test_lib_*.py))
QUICK_VARS += SCL_TEST_PATHS="$(addprefix tests/st_lib/test_lib_,protocol.py status.py modes.py \
  latching.py window.py warm.py)"

.PHONY: scl-tests
scl-tests: all
	@mkdir -p $(RESULTS)
	PLCRT_STLIB_DIALECT=scl $(PYTEST) --junitxml=$(RESULTS)/scl-tests.xml $(SCL_TEST_PATHS)
