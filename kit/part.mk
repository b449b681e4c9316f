# kit/: the test kit for integrators (issue 25, docs/test-kit.md): the mipkit package (pytest
# plugin, scenario command mip-kit), its wheel build (kit/setup.py packs the repository's own
# packages, the runtime's C sources, st_lib and libmipcosim.so) and an example integrator
# project (kit/example/). Nothing to build for `make all`: the repository's tests import mipkit
# from kit/ (tests/kit/conftest.py); an integrator installs it with `pip install CHECKOUT/kit`.
.PHONY: kit-wheel
kit-wheel: venv
	@mkdir -p $(BUILD)/kit
	$(PY) -m pip wheel -q --no-deps --no-build-isolation -w $(BUILD)/kit ./kit
