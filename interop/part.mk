# interop/: the interop matrix (issue 11). Our blocks in the soft-PLC against the note-only
# Python peer (peers/), over build/emulator/mip-emulator; the table in docs/protocol.md is
# generated from its JSON results.
PY_PACKAGES += interop
INTEROP_RESULTS := $(BUILD)/interop/matrix.json

.PHONY: interop-matrix
interop-matrix: all
	@mkdir -p $(BUILD)/interop
	$(PY) -m mipinterop --out $(INTEROP_RESULTS)
	$(PY) -m mipinterop --write-docs $(INTEROP_RESULTS)
