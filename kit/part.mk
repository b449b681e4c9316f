# kit/: the test kit for integrators (issue 25, docs/test-kit.md): the mipkit package (pytest
# plugin, scenario command mip-kit), its packaging (kit/setup.py builds one wheel of the
# repository's own packages, the runtime's C sources, st_lib and libmipcosim.so) and an example
# integrator project (kit/example/). Nothing to build for `make all`: the repository's tests
# import mipkit from kit/ (tests/kit/conftest.py); an integrator runs `pip install CHECKOUT/kit`
# or `pip install mip_logger_kit-<version>.tar.gz` (the kit's source archive, `make kit-dist`).
KIT_DIST := $(BUILD)/kit

.PHONY: kit-dist kit-wheel
# the kit's source archive: kit/ with the repository's files it is built from (kit/setup.py NEEDED)
kit-dist: venv
	@rm -rf $(KIT_DIST) && mkdir -p $(KIT_DIST)
	cd kit && $(PY) -c "from setuptools import build_meta as b; print('$(KIT_DIST)/' + b.build_sdist('$(abspath $(KIT_DIST))'))"

# a wheel for this machine (what pip builds from either)
kit-wheel: venv
	@mkdir -p $(KIT_DIST)
	$(PY) -m pip wheel -q --no-deps --no-build-isolation -w $(KIT_DIST) ./kit
