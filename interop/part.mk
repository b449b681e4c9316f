# interop/: the interop matrix (issue 11). Our blocks in the soft-PLC against the note-only
# Python peer (peers/), over build/emulator/mip-emulator; the table in docs/protocol.md is
# generated from its JSON results (interop/results.json, committed with the table).
PY_PACKAGES += interop
INTEROP_RESULTS := interop/results.json

.PHONY: interop-matrix
interop-matrix: all
	@$(PY) -m mipinterop --out $(INTEROP_RESULTS); rc=$$?; \
	$(PY) -m mipinterop --write-docs $(INTEROP_RESULTS) && exit $$rc
