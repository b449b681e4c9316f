# view/: mip-view, the live view in the browser (the mipview package, view/README.md).
PY_PACKAGES += view

.PHONY: view
# The demo's chain in the co-simulation, driven from the page: prints the URL to open.
# Options: make view VIEW_ARGS="--preset ex2 --port 8611"; a real-time run's trace:
# make view VIEW_ARGS="--follow build/plc/run/emulator-trace.jsonl" (while `make run` runs)
view: all
	@$(VENV_ABS)/bin/mip-view $(VIEW_ARGS)

.PHONY: view-shots
# The screenshots of docs/view.md, taken in Debian's Chromium (tests/view checks the committed
# ones are what this makes).
view-shots: all
	@$(PY) -m mipview.shots docs/img $(foreach p,demo ex2 ex6-outstation chain,--preset $(p))
