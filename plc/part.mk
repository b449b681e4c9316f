# plc/: the example ST programs, their generators and the real-time demos (the mip-plc
# distribution, plc/pyproject.toml): mipprograms (stdlib only; mip-glue, OpenPLC's limits and
# plc/gen_programs.py's generator: the co-simulation, the kit and the demos import it) and
# mipdemo (`make run`, plc/demo.py: above mipcosim). plc/*.st are generated and committed.
PY_PACKAGES += plc
