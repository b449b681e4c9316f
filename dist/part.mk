# dist/: the release archives of st_lib's two libraries. `make dist` writes
# build/dist/mip-logger-<version>.tar.gz and .zip (the core; version from
# st_lib/core/MIP_Version.st) and mip-logger-chain-<version>.* (the chain library; version from
# st_lib/chain/MIP_ChainVersion.st), each checked against CHANGELOG.md, the PLCopen XML inside
# validated against the TC6 v2.01 schema. See docs/releases.md.
# mkdist is also the package mipdist (dist/pyproject.toml), installed by `make venv`
PY_PACKAGES += dist
DIST_DIR := $(BUILD)/dist
# the schema is made by docs/part.mk (included after this file, so not $(PLCOPEN_XSD) here)
DIST_XSD := $(BUILD)/docs/tc6_xml_v201.xsd

.PHONY: dist dist-version
dist: $(DIST_XSD) | venv
	@rm -rf $(DIST_DIR)
	$(PY) dist/mkdist.py --xsd $(DIST_XSD) -o $(DIST_DIR)

dist-version: | venv
	@$(PY) dist/mkdist.py --version
