"""mipprograms: the repository's example ST programs (plc/) and the generators that write them.

- mipglue: `mip-glue`, the located-variable copies between a Modbus master's image and the MIP
  blocks (also for integrators: the test kit installs it);
- openplc_limits: stock OpenPLC v3's Modbus master limits, checked on an mbconfig.cfg;
- image: the one description of the logger programs' located image (plc/image/*_io.st) and
  the %MW layout read from plc/PLC_Logger.st;
- image_many: the same for plc/central_many.st, whose image also holds its N station
  instances (plc/image/central_many_io.st, any N of 1..247);
- gen (common, soe, image, image_many): the generated ST of plc/ and plc/openplc/*.cfg
  (plc/gen_programs.py runs it).

Standard library, mipprobe and stc's parser only: the co-simulation (central_many), the kit and the demos import it, it
imports none of them."""
