"""Fixtures of the runtime tests (helpers that tests import live in rt_helpers.py)."""
import sys
from pathlib import Path

import pytest

# the emulator tests' helpers (emu_support: the mip-emulator process, tcp_read) for the RTU tests
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "emulator"))

from rt_helpers import ModbusServer


def _writer(tmp_path, default_name):
    def write(text, name=default_name):
        p = tmp_path / name
        p.write_text(text)
        return p
    return write


@pytest.fixture
def st_file(tmp_path):
    """Write ST text into tmp_path and return the path."""
    return _writer(tmp_path, "prog.st")


@pytest.fixture
def conf_file(tmp_path):
    """Write a runtime config (plcrt or mbconfig.cfg) into tmp_path and return the path."""
    return _writer(tmp_path, "plc.conf")


@pytest.fixture
def server():
    """A Modbus TCP server on 127.0.0.1 (rt_helpers.ModbusServer), closed after the test."""
    srv = ModbusServer()
    yield srv
    srv.close()
