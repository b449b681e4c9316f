"""Every front end fails in one line: the executable's --check on files that are not config
files (directory, device, FIFO, NUL bytes, too large), plcrt-build on bad output paths and
sources. No traceback, no hang, no reading /dev/zero until memory runs out."""
import os
import subprocess
import sys

import pytest

from miptest.rt import TINY
from plcharness import build_program


GOOD = "[master]\npolling_period = 100ms\n[device d]\nhost = 127.0.0.1\n"


@pytest.fixture(scope="module")
def exe(tmp_path_factory):
    out = tmp_path_factory.mktemp("fe")
    src = out / "p.st"
    src.write_text(TINY)
    return build_program([src], out / "out", compiler="stc").executable


def check(exe, path):
    # a hang (reading /dev/zero, waiting on a FIFO) fails the test through the timeout
    return subprocess.run([str(exe), "--check", "-c", str(path)], capture_output=True,
                          text=True, timeout=20)


def one_line(proc):
    assert proc.returncode == 2, proc
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    return proc.stderr.strip()


@pytest.mark.parametrize("what", ["directory", "dev_zero", "fifo", "nul", "large"])
def test_check_refuses_what_is_not_a_config_file(exe, tmp_path, what):
    if what == "directory":
        path, expect = tmp_path, "a directory, not a config file"
    elif what == "dev_zero":
        path, expect = "/dev/zero", "not a regular file, not a config file"
    elif what == "fifo":
        path = tmp_path / "fifo"
        os.mkfifo(path)
        expect = "not a regular file, not a config file"
    elif what == "nul":
        # bytes after a NUL used to be ignored: the NUL starts line 5
        path = tmp_path / "nul.cfg"
        path.write_bytes(GOOD.encode() + b"\0[device e]\nhost = x = y\n")
        expect = "nul.cfg:5: error: NUL byte: not a text file"
    else:
        path = tmp_path / "large.cfg"
        path.write_bytes(GOOD.encode() + b"#" * (1 << 20) + b"\n")
        expect = "larger than 1048576 bytes"
    line = one_line(check(exe, path))
    assert line.startswith(str(path)) and expect in line, line


def test_check_accepts_a_config_of_just_under_the_limit(exe, tmp_path):
    path = tmp_path / "big.cfg"
    body = GOOD.encode()
    path.write_bytes(body + b"#" * ((1 << 20) - len(body) - 1) + b"\n")
    assert path.stat().st_size == 1 << 20
    proc = check(exe, path)
    assert proc.returncode == 0 and proc.stderr == "", proc


def build_cli(*args):
    return subprocess.run([sys.executable, "-m", "plcharness", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("out,expect", [
    ("/dev/null/x", "/dev/null/x: error: cannot create it: /dev/null is not a directory"),
    ("/proc/plcrt-test/out", "/proc/plcrt-test"),  # not writable, even by root (other message)
    ("FILE", "exists and is not a directory"),
    ("NONEMPTY", "not empty and not the output of plcrt-build: not replaced"),
])
def test_build_to_a_bad_output_path_is_one_line(tmp_path, out, expect):
    src = tmp_path / "p.st"
    src.write_text(TINY)
    if out == "FILE":
        out = tmp_path / "afile"
        out.write_text("keep me")
    elif out == "NONEMPTY":
        out = tmp_path / "mine"
        out.mkdir()
        (out / "keep.txt").write_text("keep me")
    proc = build_cli("-o", out, src)
    assert proc.returncode == 1, proc
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert expect in proc.stderr, proc.stderr
    if isinstance(out, os.PathLike):  # nothing of the user's was deleted
        assert "keep me" in ((out / "keep.txt") if out.is_dir() else out).read_text()


@pytest.mark.parametrize("src,expect", [
    ("DIR", "a directory, not an ST source"),
    ("/dev/zero", "/dev/zero: error: not a regular file, not an ST source"),
    ("MISSING", "error: no such file"),
])
def test_build_of_a_bad_source_is_one_line(tmp_path, src, expect):
    src = {"DIR": tmp_path, "MISSING": tmp_path / "missing.st"}.get(src, src)
    proc = build_cli("-o", tmp_path / "out", src)
    assert proc.returncode == 1, proc
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert expect in proc.stderr, proc.stderr


def test_build_can_rebuild_into_its_own_output(tmp_path):
    src = tmp_path / "p.st"
    src.write_text(TINY)
    for _ in range(2):
        proc = build_cli("-o", tmp_path / "out", src)
        assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out" / "plc").is_file()


@pytest.mark.parametrize("args", [[], ["-o", "x"], ["--bogus", "-o", "x", "a.st"]])
def test_build_bad_command_line_is_one_line(args):
    proc = build_cli(*args)
    assert proc.returncode == 2, proc
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("plcrt-build: error: "), proc.stderr
