"""mip-glue (plc/mipprograms/mipglue.py): the located-variable glue between a Modbus master's image and
the MIP blocks' arrays, as an integrator runs it; the kit example's and plc/'s copies are its
output; bad input is one line."""
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from kit_helpers import KIT, REPO, run
from mipcosim import programs as L
from mipprograms.common import config
from plcharness.build import matiec_available
from plcharness.plc import Plc

GLUE = Path(sys.executable).parent / "mip-glue"   # installed by `make venv` (plc/pyproject.toml)
LIB = [L.ST_LIB / f for f in L.LIB_FILES]
CONFIG = config("PROG", "g", task="t")


def glue(*args, cwd=None):
    """mip-glue as a command: the venv's console script, as the kit installs it."""
    return run([GLUE, *args], cwd or REPO)


def one_error_line(r):
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stdout == ""
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("mip-glue: error: "), r.stderr
    return lines[0]


@pytest.mark.parametrize("compiler", ["stc", pytest.param("matiec", marks=pytest.mark.skipif(
    not matiec_available(), reason="iec2c not on PATH"))])
def test_program_form_copies_every_station_block_in_a_plc(tmp_path, compiler):
    """--form program for a central of 2 stations, blocks of 4 and 3 registers at %IW300 /
    %QW110: in a PLC, station s's read registers land in rd<s>, wr<s> goes out at its own %QW."""
    r = glue("--form", "program", "--program-name", "PROG", "--stations", "2", "--read-count", "4",
             "--write-count", "3", "--read-base", "%IW300", "--write-base", "110",
             "--read-array", "rd{s}", "--write-array", "wr{s}")
    assert r.returncode == 0, r.stderr
    src = tmp_path / "glue.st"
    src.write_text(r.stdout + CONFIG)
    plc = Plc.build(LIB + [src], workdir=tmp_path / "w", compiler=compiler)
    for i in range(4):
        plc[f"%IW{300 + i}"] = 10 + i             # station 1
        plc[f"%IW{304 + i}"] = 20 + i             # station 2
    plc["g.wr1"] = [1, 2, 3] + [0] * 120
    plc["g.wr2"] = [7, 8, 9] + [0] * 120
    plc.scan()
    assert plc["g.rd1"][:5] == [10, 11, 12, 13, 0]
    assert plc["g.rd2"][:5] == [20, 21, 22, 23, 0]
    assert [plc[f"%QW{110 + i}"] for i in range(7)] == [1, 2, 3, 7, 8, 9, 0]
    plc.close()


def test_fragment_pasted_into_a_program_compiles(tmp_path):
    """The default output, pasted after the program's own VAR blocks, is the program's body."""
    r = glue("--write-array", "snd.aWrite", "--read-count", "10", "--write-count", "5")
    assert r.returncode == 0, r.stderr
    assert "r9 AT %IW109 : WORD;" in r.stdout and "w4 := snd.aWrite[4];" in r.stdout
    src = tmp_path / "frag.st"
    src.write_text("PROGRAM PROG\nVAR\n  snd : MIP_Sender;\n  aRd : MIP_T_ReadBlock;\nEND_VAR\n"
                   + r.stdout + "END_PROGRAM\n" + CONFIG)
    p = run([REPO / ".venv" / "bin" / "stc", "-o", tmp_path / "out", *LIB, src], tmp_path)
    assert p.returncode == 0, p.stderr


HAND = """PROGRAM PROG
VAR
  snapSaved AT %IW8 : WORD;
END_VAR
  (* BEGIN mip-glue declarations: mip-glue --read-count 2 *)
  (* END mip-glue declarations *)
IF rdDone THEN
    (* BEGIN mip-glue read *)
    aRd[0] := r0;   (* stale *)
    (* END mip-glue read *)
END_IF;
x := 1;   (* the integrator's own line *)
(* BEGIN mip-glue write *)
(* END mip-glue write *)
END_PROGRAM
"""


def test_update_rewrites_the_regions_in_place_and_check_catches_a_hand_edit(tmp_path):
    f = tmp_path / "prog.st"
    f.write_text(HAND)
    r = glue("--read-count", "3", "--write-count", "2", "--write-array", "snd.aWrite",
             "--update", f)
    assert r.returncode == 0 and r.stdout == f"{f}: updated declarations, read, write\n", r.stderr
    text = f.read_text()
    # the regions at their markers' indentation, everything else as it was
    assert ("    (* BEGIN mip-glue read *)\n    aRd[0] := r0;\n    aRd[1] := r1;\n"
            "    aRd[2] := r2;\n    (* END mip-glue read *)\n") in text
    assert ("  (* BEGIN mip-glue declarations: mip-glue --read-count 3 --write-count 2 "
            "--write-array snd.aWrite *)\n  VAR\n    r0 AT %IW100 : WORD;\n") in text
    assert "(* BEGIN mip-glue write *)\nw0 := snd.aWrite[0];\nw1 := snd.aWrite[1];\n(* END" in text
    assert "stale" not in text
    outside = [l for l in HAND.splitlines() if "mip-glue" not in l and "stale" not in l]
    assert [l for l in text.splitlines() if l in outside] == outside
    # the options recorded in the file: --check and --update without options agree
    r = glue("--check", f)
    assert r.returncode == 0 and r.stdout == f"{f}: up to date\n", r.stderr
    assert glue("--update", f).stdout == f"{f}: up to date\n" and f.read_text() == text
    # a hand-edited copy: --check fails in one line naming it, --update repairs it
    lines = text.splitlines()
    n = lines.index("    aRd[1] := r1;")
    lines[n] = "    aRd[1] := r2;"
    f.write_text("\n".join(lines) + "\n")
    r = glue("--check", f)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr == (f"{f}:{n + 1}: the region mip-glue read differs from what `mip-glue "
                        f"--read-count 3 --write-count 2 --write-array snd.aWrite` writes "
                        f"(run it with --update {f})\n")
    assert glue("--update", f).returncode == 0 and f.read_text() == text


BAD = [
    (["--stations", "4", "--read-array", "rd{s}", "--write-array", "wr{s}"],
     "the read blocks would take %IW100..%IW599 (4 stations x 125): stock OpenPLC v3's Modbus "
     "master fills only %IW100..%IW499 (400 registers, MAX_MB_IO): at most 3 stations of 125 "
     "registers fit (or --runtime plcrt: the whole image)"),
    (["--read-base", "450"], "the read block would take %IW450..%IW574: stock OpenPLC v3's Modbus "
     "master fills only %IW100..%IW499 (400 registers, MAX_MB_IO): --read-base 100..375 for 125 "
     "registers (or --runtime plcrt: the whole image)"),
    (["--write-base", "%QW20"], "the write block would take %QW20..%QW142: stock OpenPLC"),
    (["--read-base", "%IW950", "--runtime", "plcrt"],
     "the read block would take %IW950..%IW1074: the image ends at %IW1023 (OpenPLC v3 and plcrt)"),
    (["--read-count", "126"], "--read-count 126: 1..125 registers (one Modbus read, MIP_T_ReadBlock)"),
    (["--write-count", "124"], "--write-count 124: 0..123 registers"),
    (["--stations", "2"], "--read-array aRd: with --stations 2 every station needs its own array: "
     "put {s} (the station number) in the name, e.g. aRd{s}"),
    (["--read-prefix", "r__"], "--read-prefix 'r__': a name starts with a letter"),
    (["--read-prefix", "w"], "--read-prefix 'w' and --write-prefix 'w' give two variables the name w0"),
    (["--read-prefix", "W1"], "--read-prefix 'W1' and --write-prefix 'w' give two variables the name w10"),
    (["--read-array", "r5"], "--read-array r5: r5 is also the name of a generated located variable"),
    (["--write-array", "snd.aWrite;x"], "--write-array snd.aWrite;x: not an ST name"),
    (["--read-count", "x"], "argument --read-count: invalid int value: 'x' (see mip-glue --help)"),
    (["--read-base", "%QW100"], "argument --read-base: '%QW100': a register number or %IWn"),
    (["--form", "program", "--write-array", "snd.aWrite"],
     "--form program declares the arrays: --write-array snd.aWrite is not a plain name"),
    (["--check", "missing.st"], "missing.st: No such file or directory"),
]


@pytest.mark.parametrize("args,message", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_input_is_one_line(args, message, tmp_path):
    assert message in one_error_line(glue(*args, cwd=tmp_path))


@pytest.mark.parametrize("edit,message", [
    (lambda t: t.replace("snapSaved AT %IW8", "snapSaved AT %IW101"),
     "prog.st:3: snapSaved AT %IW101 is in the read block (%IW100..%IW101): one address, two variables"),
    (lambda t: t.replace("(* BEGIN mip-glue write *)\n(* END mip-glue write *)\n", ""),
     "prog.st: no region (* BEGIN mip-glue write *) .. (* END mip-glue write *): paste the fragment "
     "(mip-glue without --update) into it first"),
    (lambda t: t.replace("    (* END mip-glue read *)\n", ""),
     "prog.st:12: BEGIN mip-glue inside the region begun on line 8 (no END mip-glue read before it)"),
    (lambda t: t.replace("mip-glue read *)", "mip-glue read 2 *)"),
     "prog.st:8: the region mip-glue read 2 is not part of this layout (declarations, read, write)"),
], ids=["overlap", "missing-region", "unclosed", "unknown-region"])
def test_bad_file_is_one_line(edit, message, tmp_path):
    (tmp_path / "prog.st").write_text(edit(HAND))
    assert one_error_line(glue("--update", "prog.st", cwd=tmp_path)) == f"mip-glue: error: {message}"
    assert (tmp_path / "prog.st").read_text() == edit(HAND)      # nothing written


def test_update_keeps_a_windows_file_windows_and_reads_past_comments(tmp_path):
    """A file with CR LF line ends gets CR LF lines; a located address named in a comment
    (also one over several lines) is no variable and no collision."""
    f = tmp_path / "prog.st"
    hand = HAND.replace("END_PROGRAM", "(* the old glue:\n   rOld AT %IW100 : WORD; *)\nEND_PROGRAM")
    f.write_bytes(hand.replace("\n", "\r\n").encode())
    r = glue("--update", f)
    assert r.returncode == 0, r.stderr
    data = f.read_bytes()
    assert b"\r\n    aRd[1] := r1;\r\n" in data and data.count(b"\n") == data.count(b"\r\n")
    assert glue("--check", f).returncode == 0


def test_bad_options_recorded_in_the_file_are_named_as_such(tmp_path):
    f = tmp_path / "prog.st"
    f.write_text(HAND.replace("mip-glue --read-count 2", "mip-glue --read-count 200"))
    assert one_error_line(glue("--check", f)) == (
        f"mip-glue: error: {f}: the options in its declarations marker (--read-count 200): "
        f"--read-count 200: 1..125 registers (one Modbus read, MIP_T_ReadBlock)")


def test_a_file_that_cannot_be_written_is_one_line(tmp_path, monkeypatch, capsys):
    """(In process: the tests may run as root, who writes read-only files.)"""
    import builtins
    from mipprograms import mipglue as mod

    def read_only(path, mode="r", *a, **k):
        if "w" in mode:
            raise PermissionError(13, "Permission denied", str(path))
        return builtins.open(path, mode, *a, **k)
    monkeypatch.setattr(mod, "open", read_only, raising=False)
    f = tmp_path / "prog.st"
    f.write_text(HAND)
    assert mod.main(["--update", str(f)]) == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err == f"mip-glue: error: {f}: Permission denied\n"
    assert f.read_text() == HAND


@pytest.mark.parametrize("program", ["Outstation.st", "RelayStation.st", "WinccCentral.st"])
def test_kit_example_glue_is_what_its_command_writes(example, program):
    """Each program of the example names the command that wrote its copies of the modem's
    blocks: run in the example project it changes nothing, --check (the recorded options)
    passes, and a drifted copy is caught."""
    f = example / "st" / program
    text = f.read_text()
    m = re.search(r"in this folder:\n\s+(mip-glue .*)\n", text)
    assert m, f"st/{program} no longer names the mip-glue command"
    words = shlex.split(m.group(1))
    assert "--update" in words
    r = glue(*words[1:], cwd=example)
    assert r.returncode == 0 and r.stdout == f"st/{program}: up to date\n", r.stdout + r.stderr
    assert f.read_text() == text
    assert glue("--check", f"st/{program}", cwd=example).returncode == 0
    # every located register variable of the program is generated (none left by hand)
    regions = re.findall(r"\(\* BEGIN mip-glue (\w+)[^\n]*\n(.*?)\(\* END mip-glue \1 \*\)", text, re.S)
    assert [k for k, _ in regions] == ["declarations", "read", "write"]
    body = re.sub(r"\(\* BEGIN mip-glue.*?END mip-glue \w+ \*\)", "", text, flags=re.S)
    assert not re.search(r"AT %[IQ]W1\d\d\b|aRd\[\d+\] :=|:= \w+\.aWrite\[", body)
    assert len(regions[0][1].splitlines()) == 2 + 125 + 123
    assert text.count("  aRd[7] := r7;\n") == 1
    f.write_text(text.replace("  aRd[7] := r7;\n", "  aRd[7] := r8;\n"))
    r = glue("--check", f"st/{program}", cwd=example)
    assert r.returncode == 1 and "the region mip-glue read differs" in r.stderr


@pytest.mark.parametrize("program,args,indent", [
    ("image/central_io.st", ["--stations", "4", "--read-array", "m{s}.aRead", "--write-array",
                             "m{s}.aWrite", "--runtime", "plcrt"], ""),
    ("image/central_many_io.st", ["--read-prefix", "r_", "--write-prefix", "w_", "--read-array",
                                  "m.aRead", "--write-array", "m.aWrite"], ""),
])
def test_plc_programs_copies_are_what_mip_glue_writes(program, args, indent):
    """plc/gen_programs.py writes its copies with the same generator: the example programs
    hold, line for line, what an integrator's mip-glue writes for their layout."""
    r = glue(*args)
    assert r.returncode == 0, r.stderr
    text = (REPO / "plc" / program).read_text()
    regions = re.findall(r"\(\* BEGIN mip-glue ([\w ]+?)(?:: [^\n]*)? \*\)\n(.*?)\(\* END mip-glue \1 \*\)",
                         r.stdout, re.S)
    assert len(regions) == 1 + 2 * (4 if program == "image/central_io.st" else 1)
    decl = regions[0][1].splitlines()[1:-1]        # without VAR / END_VAR
    start = 0
    for line in decl:                              # in order (the handshake lines between stations)
        start = text.index(line + "\n", start)
    for key, body in regions[1:]:
        block = "".join(indent + line + "\n" for line in body.splitlines())
        assert block in text, f"{program}: the {key} copies differ from mip-glue's"


def test_help_is_usage_and_options():
    r = glue("--help")
    assert r.returncode == 0 and r.stdout.startswith("usage: mip-glue [layout options]")
    for opt in ("--read-base", "--read-count", "--write-base", "--write-count", "--stations",
                "--read-array", "--write-array", "--read-prefix", "--write-prefix", "--runtime",
                "--form", "--update", "--check"):
        assert f"\n  {opt}" in r.stdout, opt


def test_installed_mip_glue_runs_outside_the_checkout(tmp_path):
    """The kit's wheel installs the command `mip-glue`; it needs nothing of the checkout
    (stock OpenPLC's limits come with it)."""
    r = run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
             "--no-index", "-w", tmp_path / "whl", KIT], tmp_path)
    assert r.returncode == 0, r.stderr
    (whl,) = (tmp_path / "whl").glob("mip_logger_kit-*.whl")
    r = run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index",
             "--target", tmp_path / "site", whl], tmp_path)
    assert r.returncode == 0, r.stderr
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(tmp_path / "site"), "LC_ALL": "C.UTF-8"}
    cmd = tmp_path / "site" / "bin" / "mip-glue"
    p = subprocess.run([cmd, "--read-count", "2", "--write-count", "1"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and "r1 AT %IW101 : WORD;\n" in p.stdout, p.stderr
    p = subprocess.run([cmd, "--read-base", "450"], cwd=tmp_path, env=env, capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 2 and "fills only %IW100..%IW499 (400 registers" in p.stderr, p.stderr
    p = subprocess.run([sys.executable, "-c", "import mipprograms.mipglue as g; print(g.__file__)"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60)
    assert str(tmp_path / "site") in p.stdout and str(REPO) not in p.stdout, p.stdout + p.stderr
