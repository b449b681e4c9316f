"""The stc command line as a user sees it: usage errors, exit codes, error format, outputs."""
import os
import re
import subprocess

import stc_harness as H

GOOD = """PROGRAM Main
VAR x : INT; END_VAR
x := x + 1;
END_PROGRAM
CONFIGURATION Config0
RESOURCE Res0 ON PLC
TASK t(INTERVAL := T#20ms, PRIORITY := 0);
PROGRAM Main0 WITH t : Main;
END_RESOURCE
END_CONFIGURATION
"""


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_version():
    r = H.run_stc(["--version"])
    assert r.returncode == 0
    assert re.match(r"stc \d+\.\d+", r.stdout)


def test_help_documents_include_dirs():
    r = H.run_stc(["--help"])
    assert r.returncode == 0
    assert "-I DIR" in r.stdout and "library" in r.stdout
    assert "-o OUTDIR" in r.stdout


def test_no_arguments_is_usage_error():
    r = H.run_stc([])
    assert r.returncode == 2
    assert "usage:" in r.stderr and "error" in r.stderr


def test_missing_outdir_is_usage_error(tmp_path):
    r = H.run_stc([write(tmp_path, "a.st", GOOD)])
    assert r.returncode == 2
    assert "-o" in r.stderr


def test_unknown_option_is_usage_error(tmp_path):
    r = H.run_stc(["--frobnicate", "-o", str(tmp_path / "o"), write(tmp_path, "a.st", GOOD)])
    assert r.returncode == 2


def test_missing_input_file(tmp_path):
    r = H.run_stc(["-o", str(tmp_path / "o"), str(tmp_path / "nope.st")])
    assert r.returncode == 1
    assert "nope.st" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_bad_include_dir(tmp_path):
    r = H.run_stc(["-I", str(tmp_path / "nodir"), "-o", str(tmp_path / "o"), write(tmp_path, "a.st", GOOD)])
    assert r.returncode == 1
    assert "nodir" in r.stderr


def test_outdir_not_writable(tmp_path):
    blocker = write(tmp_path, "file", "x")
    r = H.run_stc(["-o", os.path.join(blocker, "sub"), write(tmp_path, "a.st", GOOD)])
    assert r.returncode == 1
    assert "Traceback" not in r.stderr and r.stderr.startswith("stc: error:")


def test_outputs_written(tmp_path):
    out = tmp_path / "o"
    r = H.run_stc(["-o", str(out), write(tmp_path, "a.st", GOOD)])
    assert r.returncode == 0, r.stderr
    names = set(os.listdir(out))
    assert {"POUS.c", "POUS.h", "Config0.c", "RES0.c", "LOCATED_VARIABLES.h", "SYMBOLS.tsv",
            "SOURCES.txt", "stc_rt.h", "RETAIN.c"} <= names
    assert (out / "SOURCES.txt").read_text().split() == ["POUS.c", "Config0.c", "RES0.c",
                                                         "RETAIN.c"]
    cfg = (out / "Config0.c").read_text()
    assert "common_ticktime__ = 20000000ULL" in cfg
    assert "void config_init__(void)" in cfg and "void config_run__(unsigned long tick)" in cfg
    sym = (out / "SYMBOLS.tsv").read_text().splitlines()
    assert sym[0] == "# stc symbols v1"
    assert "CONFIG0.RES0.MAIN0.X\tINT\tVAR\tRES0__MAIN0.X" in sym


def test_errors_are_file_line_col_and_all_reported(tmp_path):
    bad = write(tmp_path, "bad.st", "PROGRAM Main\nVAR x : INT; u : UINT; END_VAR\nx := u;\nu := x;\nEND_PROGRAM\n")
    r = H.run_stc(["-o", str(tmp_path / "o"), bad])
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert lines == [
        f"{bad}:3:6: error: assignment: type UINT cannot be assigned to INT without explicit "
        "conversion (IEC strict typing): use UINT_TO_INT(...) [S0506]",
        f"{bad}:4:6: error: assignment: type INT cannot be assigned to UINT without explicit "
        "conversion (IEC strict typing): use INT_TO_UINT(...) [S0506]",
    ]
    assert not (tmp_path / "o").exists(), "no output on errors"


def test_errors_of_several_files(tmp_path):
    a = write(tmp_path, "a.st", "PROGRAM A\nVAR x : INT; END_VAR\nx := 1 +;\nEND_PROGRAM\n")
    b = write(tmp_path, "b.st", "PROGRAM B\nVAR x : INT; END_VAR\nx := * 1;\nEND_PROGRAM\n")
    r = H.run_stc(["-o", str(tmp_path / "o"), a, b])
    assert r.returncode == 1
    assert f"{a}:3:9: error:" in r.stderr and f"{b}:3:6: error:" in r.stderr


def test_binary_garbage_no_traceback(tmp_path):
    p = tmp_path / "junk.st"
    p.write_bytes(bytes(range(256)) * 4)
    r = H.run_stc(["-o", str(tmp_path / "o"), str(p)])
    assert r.returncode == 1
    assert "Traceback" not in r.stderr and "internal" not in r.stderr
    assert re.match(rf"{re.escape(str(p))}:\d+:\d+: error: ", r.stderr)


def test_empty_file_is_accepted_and_compiles(tmp_path):
    out = tmp_path / "o"
    r = H.run_stc(["-o", str(out), write(tmp_path, "empty.st", "")])
    assert r.returncode == 0, r.stderr
    for c in (out / "SOURCES.txt").read_text().split():
        p = subprocess.run(["cc"] + H.CFLAGS + ["-c", "-o", os.devnull, str(out / c)],
                           capture_output=True, text=True)
        assert p.returncode == 0, p.stderr


def test_include_dir_library(tmp_path):
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "twice.st").write_text("FUNCTION Twice : INT\nVAR_INPUT a : INT; END_VAR\nTwice := a * 2;\nEND_FUNCTION\n")
    main = write(tmp_path, "main.st", GOOD.replace("x := x + 1;", "x := Twice(21);"))
    exe_dir = tmp_path / "w"
    exe_dir.mkdir()
    r = H.run_stc(["-I", str(lib), "-o", str(tmp_path / "o"), main])
    assert r.returncode == 0, r.stderr
    # the same file given twice (directly and by -I) is read once
    r = H.run_stc(["-I", str(lib), "-o", str(tmp_path / "o2"), main, str(lib / "twice.st")])
    assert r.returncode == 0, r.stderr
    r = H.run_stc(["-o", str(tmp_path / "o3"), main])
    assert r.returncode == 1 and "unknown function 'TWICE'" in r.stderr


def test_deterministic_output(tmp_path):
    src = os.path.join(H.HERE, "accept", "struct_nested.st")
    outs = []
    for i in range(2):
        out = tmp_path / f"o{i}"
        r = H.run_stc(["-o", str(out), src])
        assert r.returncode == 0, r.stderr
        outs.append({n: (out / n).read_bytes() for n in sorted(os.listdir(out))})
    assert outs[0] == outs[1]
    # and independent of the hash seed of the Python process
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = tmp_path / "o3"
    subprocess.run(H.stc_cmd() + ["-o", str(out), src], env=env, check=True)
    assert {n: (out / n).read_bytes() for n in sorted(os.listdir(out))} == outs[0]


def test_whole_corpus_deterministic(tmp_path):
    files = sorted(os.path.join(H.HERE, "accept", f) for f in os.listdir(os.path.join(H.HERE, "accept")))
    blobs = []
    for seed in ("1", "2"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        data = []
        for i, f in enumerate(files[:30]):
            out = tmp_path / f"{seed}_{i}"
            subprocess.run(H.stc_cmd() + ["-o", str(out), f], env=env, check=True, capture_output=True)
            data.append({n: (out / n).read_bytes() for n in sorted(os.listdir(out))})
        blobs.append(data)
    assert blobs[0] == blobs[1]
