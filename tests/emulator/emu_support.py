"""Moved to the test-helper package: miptest.emu (tests/support/). This name stays only for
tests/runtime (test_rt_rtu.py, test_rt_rtu_link.py, test_rt_unit_word.py), whose conftest adds
tests/emulator to the import path for it; once they import miptest.emu, delete this file."""
from miptest.emu import Emulator, tcp_read  # noqa: F401
