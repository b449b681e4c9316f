# model/: the spin (Promela) model of the record protocol (st_lib/PROTOCOL.md, issue 11):
# modems, time-slot radio with loss and link repeat, restarts, our blocks and note-only peers.
# `make model-check` checks every configuration, both layouts (about 35 minutes on 2 cores); part of
# `make test`; docs/dev/model.md explains the model and the verdicts.
MODEL_ARGS ?=

C_TESTS += model-check

.PHONY: model-check
model-check:
	@mkdir -p $(RESULTS) $(BUILD)/model
	python3 model/run.py --work $(BUILD)/model --junit $(RESULTS)/model.xml $(MODEL_ARGS)
