"""Fixtures of the runtime tests (helpers that tests import live in miptest.rt, tests/support/)."""

import pytest

from miptest.rt import ModbusServer


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
    """A Modbus TCP server on 127.0.0.1 (miptest.rt.ModbusServer), closed after the test."""
    srv = ModbusServer()
    yield srv
    srv.close()
