"""Refuses an OpenPLC v3 `mbconfig.cfg` that stock OpenPLC cannot hold.

    .venv/bin/python plc/openplc_limits.py plc/openplc/*.cfg

Stock OpenPLC v3's Modbus master copies every device's ranges into four buffers of
MAX_MB_IO = 400 entries each, one per direction and kind, and never checks their size:

    registers read   Input_Registers + Holding_Registers_Read of all devices  -> %IW100..%IW499
    registers written Holding_Registers of all devices                         <- %QW100..%QW499
    bits read        Discrete_Inputs of all devices                            -> %IX100.0..
    bits written     Coils of all devices                                      <- %QX100.0..

More than 400 in one of them overruns OpenPLC's buffers (a fourth 125-register MIP station put
memory from past the buffer on air). This checker sums each direction over the devices in the
order OpenPLC maps them and reports the first one over 400 in one line:
FILE:LINE: error: ... (exit 1). plc/gen_programs.py runs the same check on the files it writes.
"""
from __future__ import annotations

import re
import sys

MAX_MB_IO = 400
# (what, keys summed, image)
DIRECTIONS = [
    ("registers read", ("Input_Registers_Size", "Holding_Registers_Read_Size"), "%IW100..%IW499"),
    ("registers written", ("Holding_Registers_Size",), "%QW100..%QW499"),
    ("bits read", ("Discrete_Inputs_Size",), "%IX100.0..%IX149.7"),
    ("bits written", ("Coils_Size",), "%QX100.0..%QX149.7"),
]
LINE = re.compile(r'^\s*([A-Za-z_][\w.]*)\s*=\s*"?([^"]*?)"?\s*$')


class LimitError(Exception):
    """One line: FILE:LINE: error: MESSAGE."""


def parse(text: str, name: str):
    """(Num_Devices, {device index: {key: (value, line)}}) of an mbconfig.cfg."""
    num, devices = None, {}
    for lineno, raw in enumerate(text.splitlines(), 1):
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        m = LINE.match(s)
        if not m:
            raise LimitError(f"{name}:{lineno}: error: expected 'key = \"value\"'")
        key, val = m.groups()
        if key == "Num_Devices":
            if not val.isdigit():
                raise LimitError(f"{name}:{lineno}: error: Num_Devices: '{val}' is not a number")
            num = int(val)
            continue
        d = re.fullmatch(r"device(\d+)\.(\w+)", key)
        if d:
            devices.setdefault(int(d.group(1)), {})[d.group(2)] = (val, lineno)
    if num is None:
        raise LimitError(f"{name}:1: error: Num_Devices missing")
    return num, devices


def check(text: str, name: str) -> None:
    """Raises LimitError for the first direction over MAX_MB_IO."""
    num, devices = parse(text, name)
    for what, keys, image in DIRECTIONS:
        total, parts = 0, []
        for i in range(num):
            dev = devices.get(i, {})
            for k in keys:
                val, line = dev.get(k, ("0", 0))
                if not val.isdigit():
                    raise LimitError(f"{name}:{line}: error: device{i}.{k}: '{val}' is not a number")
                n = int(val)
                if n == 0:
                    continue
                total += n
                parts.append(n)
                if total > MAX_MB_IO:
                    sizes = " + ".join(str(p) for p in parts)
                    raise LimitError(
                        f"{name}:{line}: error: {total} {what} ({sizes}, up to device{i}.{k}): "
                        f"stock OpenPLC v3 holds at most {MAX_MB_IO} {what} over all devices "
                        f"({image}, MAX_MB_IO) and overruns its buffer beyond")


def check_file(path: str) -> None:
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise LimitError(f"{path}: error: {e.strerror}") from None
    check(text, path)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__.strip().splitlines()[0] + "\n\nusage: openplc_limits.py MBCONFIG.cfg...",
              file=sys.stderr if not argv else sys.stdout)
        return 2 if not argv else 0
    bad = 0
    for path in argv:
        try:
            check_file(path)
        except LimitError as e:
            print(e, file=sys.stderr)
            bad = 1
    return bad


if __name__ == "__main__":
    sys.exit(main())
