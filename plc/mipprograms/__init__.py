"""mipprograms: the repository's example ST programs (plc/) and the generators that write them.

- mipglue: `mip-glue`, the located-variable copies between a Modbus master's image and the MIP
  blocks (also for integrators: the test kit installs it);
- openplc_limits: stock OpenPLC v3's Modbus master limits, checked on an mbconfig.cfg;
- gen (common, logger, soe): plc/*.st and plc/openplc/*.cfg (plc/gen_programs.py runs it).

Standard library only: the co-simulation (central_many), the kit and the demos import it, it
imports none of them."""
