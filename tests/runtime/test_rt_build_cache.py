"""The build cache (runtime_shim/README.md): the runtime's own C sources are compiled once per
compiler and flags, not in every program's build; each program's build still compiles the
program, and the executables run."""
import os
import subprocess

from plcharness import build_program
from miptest.rt import COUNTER, TINY

CORE = ("plcrt_core.c", "plcrt_image.c", "plcrt_config.c", "plcrt_master.c", "plcrt_transport.c",
        "plcrt_serial_line.c", "plcrt_slave.c", "plcrt_retain.c", "plcrt_main.c")


def counting_cc(tmp_path, monkeypatch, cache):
    """CC: the system's cc, each call's arguments appended to a log; returns a function that
    gives the runtime sources compiled since it was last called."""
    log = tmp_path / "cc.log"
    cc = tmp_path / "cc"
    cc.write_text(f'#!/bin/sh\necho "$*" >> "{log}"\nexec cc "$@"\n')
    cc.chmod(0o755)
    monkeypatch.setenv("CC", str(cc))
    monkeypatch.setenv("PLCRT_CACHE", cache)
    seen = [0]

    def compiled():
        lines = log.read_text().splitlines() if log.exists() else []
        new, seen[0] = lines[seen[0]:], len(lines)
        return sorted({os.path.basename(a) for l in new for a in l.split() if a.endswith(CORE)})
    return compiled


def runs(res):
    p = subprocess.run([str(res.executable), "-m", "virtual", "-n", "3"], capture_output=True,
                       text=True, timeout=30)
    assert p.returncode == 0, p.stderr


def test_the_runtime_is_compiled_once_for_many_programs(tmp_path, monkeypatch):
    compiled = counting_cc(tmp_path, monkeypatch, str(tmp_path / "cache"))
    for i, prog in enumerate((TINY, COUNTER)):
        (tmp_path / f"p{i}.st").write_text(prog)
    runs(build_program([tmp_path / "p0.st"], tmp_path / "out0", compiler="stc"))
    assert compiled() == sorted(CORE)
    res = build_program([tmp_path / "p1.st"], tmp_path / "out1", compiler="stc")
    assert compiled() == []
    runs(res)
    # other flags: other objects
    res = build_program([tmp_path / "p1.st"], tmp_path / "out2", compiler="stc",
                        cflags=["-DPLCRT_TEST_FLAG=1"])
    assert compiled() == sorted(CORE)
    runs(res)


def test_without_a_cache_the_build_compiles_the_runtime_into_its_output(tmp_path, monkeypatch):
    compiled = counting_cc(tmp_path, monkeypatch, "off")
    (tmp_path / "p.st").write_text(TINY)
    runs(build_program([tmp_path / "p.st"], tmp_path / "out", compiler="stc"))
    assert compiled() == sorted(CORE)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == \
        ["gen", "libplc.so", "plc", "plcrt_symbols.c", "symbols.json"]
