"""Test helpers shared by more than one folder of tests/ (issue 45: test helpers are one package
or the conftests, not modules imported across test folders by path).

A helper that one folder uses stays in that folder (its conftest.py or a plain module beside its
tests); one that a second folder needs moves here. `make venv` installs this package editable
(tests/part.mk: PY_PACKAGES), like every other part.

    miptest.emu    the real mip-emulator server for a test, raw Modbus TCP helpers, its trace
    miptest.rtu    a minimal Modbus RTU client on a pty: frames and CRC built by hand
    miptest.soe    the SOE relay's scripted events and the entries a logger must store
"""
