# model/: the spin (Promela) model of the record protocol (st_lib/PROTOCOL.md, issue 11):
# modems, time-slot radio with loss and link repeat, restarts, our blocks and note-only peers.
# `make model-check` checks every configuration but the large ones (make check); `make
# model-large` those (make check-large; model/configs.py LARGE says which and why; CI runs
# both); make test checks the quick set (one configuration of each family, model/run.py
# --quick); docs/dev/model.md explains the model, the searches and the verdicts. MODEL_JOBS
# searches run side by side.
MODEL_ARGS ?=
MODEL_JOBS ?= $(JOBS)

C_TESTS += model-check
QUICK_VARS += MODEL_ARGS=--quick

.PHONY: model-check model-large model-deep
model-check:
	@mkdir -p $(RESULTS) $(BUILD)/model
	python3 model/run.py -j $(MODEL_JOBS) --tier check --work $(BUILD)/model --junit $(RESULTS)/model-check.xml $(MODEL_ARGS)

LARGE_SUITES += model-large
model-large:
	@mkdir -p $(RESULTS) $(BUILD)/model
	python3 model/run.py -j $(MODEL_JOBS) --tier large --work $(BUILD)/model --junit $(RESULTS)/model-large.xml $(MODEL_ARGS)

# Not in make check: the whole searches of the configurations make check searches bounded
# (model/configs.py BOUNDED), one at a time with -DCOLLAPSE; 8 to 20 min and up to MODEL_DEEP_MEMLIM
# MB each (docs/dev/model.md, "The pipelined sender, retained"). For a machine with that memory.
MODEL_DEEP_MEMLIM ?= 9000
model-deep:
	@mkdir -p $(BUILD)/model-deep
	python3 model/run.py -j 1 --collapse --memlim $(MODEL_DEEP_MEMLIM) --bounded-memlim 0 --timeout 3600 \
	  -k warm/win2/ours-ours/spont/ -x +wrst-rcv --work $(BUILD)/model-deep
