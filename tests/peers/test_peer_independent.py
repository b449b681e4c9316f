"""The stand-ins written from the vendors' documents alone stay independent (peers/README.md):
each imports only the standard library (no pymodbus: its Modbus framing is its own), nothing of
the emulator, st_lib, the co-simulation or the rest of mippeer."""
import ast
import sys
from pathlib import Path

import pytest

PEERS = Path(__file__).resolve().parents[2] / "peers" / "mippeer"


@pytest.mark.parametrize("name", ["siprotec.py", "scada.py", "unicos.py"])
def test_the_stand_in_imports_the_standard_library_only(name):
    mods = set()
    for node in ast.walk(ast.parse((PEERS / name).read_text())):
        if isinstance(node, ast.Import):
            mods |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{name}: a relative import"
            mods.add(node.module.split(".")[0])
    assert mods and mods <= set(sys.stdlib_module_names), mods - set(sys.stdlib_module_names)
