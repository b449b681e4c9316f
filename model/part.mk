# model/: the spin (Promela) model of the record protocol (st_lib/PROTOCOL.md, issue 11):
# modems, time-slot radio with loss and link repeat, restarts, our blocks and note-only peers.
# `make model-check` checks every configuration, both layouts (make check); make test checks
# the quick set (one configuration of each family, model/run.py --quick); docs/dev/model.md
# explains the model, the searches and the verdicts. MODEL_JOBS searches run side by side.
MODEL_ARGS ?=
MODEL_JOBS ?= $(JOBS)

C_TESTS += model-check
QUICK_VARS += MODEL_ARGS=--quick

.PHONY: model-check
model-check:
	@mkdir -p $(RESULTS) $(BUILD)/model
	python3 model/run.py -j $(MODEL_JOBS) --work $(BUILD)/model --junit $(RESULTS)/model-check.xml $(MODEL_ARGS)
