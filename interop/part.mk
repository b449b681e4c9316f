# interop/: the interop matrix (issue 11). Our blocks in the soft-PLC against the note-only
# Python peer (peers/), both in the co-simulation kernel in virtual time
# (INTEROP_ARGS=--realtime: processes over build/emulator/mip-emulator); the table in
# docs/protocol.md is generated from its JSON results (interop/results.json, committed with it).
PY_PACKAGES += interop
INTEROP_RESULTS := interop/results.json
INTEROP_ARGS ?=

.PHONY: interop-matrix
interop-matrix: all
	@$(PY) -m mipinterop --out $(INTEROP_RESULTS) $(INTEROP_ARGS); rc=$$?; \
	$(PY) -m mipinterop --write-docs $(INTEROP_RESULTS) && exit $$rc
