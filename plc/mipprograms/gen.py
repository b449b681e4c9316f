"""Writes the generated ST of plc/: the located images plc/image/<name>_io.st of the hand-written
programs (the logger programs' from mipprograms.image, the chain's outstation_soe, central_soe
and central_push from mipprograms.image_chain, and central_many's with its N station instances
from mipprograms.image_many) and the OpenPLC v3 Modbus configurations
plc/openplc/{outstation,central}-mbconfig.cfg.

Portable ST cannot index located variables, so the copies between the located Modbus image
and the MIP blocks' arrays are one statement per register; this generator writes them with
the glue generator of `mip-glue` (mipprograms.mipglue: one implementation). Run it after
changing the layout (plc/README.md, "Register layout"); the outputs are committed.

    .venv/bin/python plc/gen_programs.py [--openplc-stations N] [--many-stations N] [-o DIR]

--openplc-stations sets how many stations the central's OpenPLC configuration serves
(default 2). Stock OpenPLC's Modbus master holds at most 400 registers per direction
(mipprograms.openplc_limits): with the 125-register read block that is 3 stations, and a
larger number is refused with one line before anything is written.
--many-stations sets how many receivers plc/image/central_many_io.st gives plc/central_many.st
(default 8; the co-simulation and the benchmark generate it for up to 247 stations).
"""
import argparse
import sys
from pathlib import Path

from mipprobe.regmap import MDP810, TRM810

from .common import OPENPLC_STATIONS, MAX_STATIONS, READ_REGS, WRITE_REGS
from .image import IMAGES, ImageError, generate as generate_image, io_file
from .image_many import MANY_STATIONS, MAX_UNIT, NAME as MANY, generate as generate_many
from .openplc_limits import MAX_MB_IO, LimitError, check as check_openplc
from . import image_chain

# where the outputs go without -o: the checkout's plc/ (this package lives in plc/mipprograms/)
PLC_DIR = Path(__file__).resolve().parents[1]


def mbconfig(devices):
    """An OpenPLC v3 mbconfig.cfg: devices = [(name, slave id, port, read start, write start)];
    each reads READ_REGS holding registers and writes WRITE_REGS (static MIP mode)."""
    out = [f'Num_Devices = "{len(devices)}"', 'Polling_Period = "100"', 'Timeout = "1000"']
    for i, (name, unit, port, rd, wr) in enumerate(devices):
        fields = [("name", name), ("slave_id", unit), ("protocol", "TCP"),
                  ("address", "127.0.0.1"), ("IP_Port", port), ("RTU_Baud_Rate", 115200),
                  ("RTU_Parity", "None"), ("RTU_Data_Bits", 8), ("RTU_Stop_Bits", 1),
                  ("RTU_TX_Pause", 0), ("Discrete_Inputs_Start", 0), ("Discrete_Inputs_Size", 0),
                  ("Coils_Start", 0), ("Coils_Size", 0), ("Input_Registers_Start", 0),
                  ("Input_Registers_Size", 0), ("Holding_Registers_Read_Start", rd),
                  ("Holding_Registers_Read_Size", READ_REGS), ("Holding_Registers_Start", wr),
                  ("Holding_Registers_Size", WRITE_REGS)]
        out += [f'device{i}.{k} = "{v}"' for k, v in fields]
    return "\n".join(out) + "\n"


def openplc_configs(stations):
    """The OpenPLC configurations: the outstation (TRM-810, port 15021) and a central with one
    device per station (MDP-810 port 15020, unit id = station)."""
    trm, mdp = TRM810, MDP810
    return [("openplc/outstation-mbconfig.cfg",
             mbconfig([("trm", 1, 15021, trm.read_status, trm.write_data)])),
            ("openplc/central-mbconfig.cfg",
             mbconfig([(f"mdp{s}", s, 15020, mdp.read_status, mdp.write_data)
                       for s in range(1, stations + 1)]))]


def main(argv=()):
    ap = argparse.ArgumentParser(prog="gen_programs.py", description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--openplc-stations", type=int, default=OPENPLC_STATIONS, metavar="N",
                    help=f"stations in the central's OpenPLC configuration "
                         f"(default {OPENPLC_STATIONS}, at most {MAX_MB_IO // READ_REGS})")
    ap.add_argument("--many-stations", type=int, default=MANY_STATIONS, metavar="N",
                    help=f"receivers of plc/central_many.st, the central of a large network "
                         f"(default {MANY_STATIONS}, 1..{MAX_UNIT})")
    ap.add_argument("-o", "--outdir", help="write here instead of plc/")
    a = ap.parse_args(list(argv))
    out = Path(a.outdir) if a.outdir else PLC_DIR
    if not 1 <= a.openplc_stations <= MAX_STATIONS:
        print(f"gen_programs.py: error: --openplc-stations {a.openplc_stations}: the central "
              f"program has stations 1..{MAX_STATIONS}", file=sys.stderr)
        return 2
    if not 1 <= a.many_stations <= MAX_UNIT:
        print(f"gen_programs.py: error: --many-stations {a.many_stations}: one MDP-810 serves "
              f"unit ids 1..{MAX_UNIT}", file=sys.stderr)
        return 2
    # the located image of the hand-written programs (plc/<name>.st): plc/image/<name>_io.st
    try:
        files = [(io_file(img.name), generate_image(img)) for img in IMAGES]
        files += [(io_file(img.name), image_chain.generate(img)) for img in image_chain.IMAGES]
        files += [(io_file(MANY), generate_many(a.many_stations))]     # and its N stations
    except ImageError as e:
        print(f"gen_programs.py: {e}", file=sys.stderr)
        return 2
    files += openplc_configs(a.openplc_stations)
    for name, text in files:              # check everything before writing anything
        if name.endswith(".cfg"):
            try:
                check_openplc(text, f"plc/{name}")
            except LimitError as e:
                print(f"gen_programs.py: {e} (--openplc-stations {a.openplc_stations}: "
                      f"at most {MAX_MB_IO // READ_REGS} stations of {READ_REGS} registers)",
                      file=sys.stderr)
                return 2
    for name, text in files:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)
        print(f"wrote plc/{name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
