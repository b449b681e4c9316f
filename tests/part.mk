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
