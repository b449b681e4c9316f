"""plcharness: build Structured Text into the plcrt soft-PLC runtime and drive it from pytest.

    from plcharness import Plc
    plc = Plc.build(["prog.st"], workdir=tmp_path)
    plc.scan(10)
    assert plc["MAIN.counter"] == 10
"""
from .build import BuildError, build_program
from .plc import Plc, PlcError

__all__ = ["Plc", "PlcError", "BuildError", "build_program"]
