"""plcharness.config (the Python model of the plcrt config) held to the C parser, the authority:
the same keys per section, what the model writes is what plcrt accepts, and where the reader
stops on the grammar plcrt stops on the same line."""
import random
import re
import subprocess

import pytest

from plcharness import build_program
from plcharness import config as model
from rt_helpers import GOOD, REPO, compiler_param, mangle, one_task

C_PARSER = REPO / "runtime_shim" / "src" / "plcrt_config.c"

# a RETAIN variable: plcrt refuses a [retain] handshake for a program without one
RETAINED = one_task("""
PROGRAM MAIN
VAR RETAIN x : INT; END_VAR
x := x + 1;
END_PROGRAM
""")


@pytest.fixture(scope="module")
def check(tmp_path_factory):
    """check(text) -> (exit code, error line): plcrt --check on the text (exit 0 or 2)."""
    tmp = tmp_path_factory.mktemp("cfgmodel")
    (tmp / "prog.st").write_text(RETAINED)
    exe = build_program([tmp / "prog.st"], tmp / "out", compiler="stc").executable
    cfg = tmp / "plc.conf"

    def run(text):
        cfg.write_bytes(text.encode("utf-8", "surrogateescape"))
        p = subprocess.run([str(exe), "--check", "-c", str(cfg)], capture_output=True, text=True,
                           errors="replace", timeout=30)
        assert p.returncode in (0, 2), (text, p.stderr)
        errors = [ln for ln in p.stderr.splitlines() if ": error: " in ln]
        assert len(errors) == (p.returncode == 2), (text, p.stderr)
        return p.returncode, "".join(errors).replace(str(cfg), "plc.conf")
    return run


def test_the_model_knows_every_key_of_the_c_parser():
    """Each section's keys as plcrt_config.c lists them in its 'unknown key' messages."""
    src = C_PARSER.read_text()
    found = {}
    for kind, keys in re.findall(r"unknown key '%s' in \[(\w+)\] \(([^)%]*)", src):
        found[kind] = tuple(k.strip() for k in keys.split(","))
    rng = re.search(r"unknown key '%s' in \[%s\] \(([^%]*)%s\)", src).group(1)
    found["write"] = tuple(k.strip() for k in rng.split(","))
    found["read"] = found["write"] + ("status_first",)
    assert found == model.KEYS
    sections = re.search(r"unknown section \[%s\] \(([^)]*)\)", src).group(1)
    assert set(s.strip() for s in sections.split(",")) == set(model.KEYS)


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_what_the_model_writes_plcrt_accepts(compiler, check):
    """A config with every section, written by the model, passes plcrt --check; read back it is
    the same config."""
    cfg = model.Config(comment="every section of a plcrt config")
    cfg.add("master", polling_period="100ms", timeout="1s", reconnect_min="100ms",
            reconnect_max="2s")
    cfg.add("slave", host="127.0.0.1", port=0, idle_timeout="10s", byte_timeout="500ms",
            watch="%QW5", watch_count="%IW5")
    cfg.add("retain", file="plc.retain", period="1s", request="%QX8.0", saved="%IW8")
    cfg.add("device", "tcp", host="127.0.0.1", port=502, unit_id="%QW2", timeout="1s",
            polling_period="50ms", errors="%IW30", online="%IX9.0", fc23="yes")
    cfg.add("device", "rtu", serial="/dev/ttyS0", baud=19200, parity="even", data_bits=8,
            stop_bits=1, pause="5ms", unit_id=3)
    cfg.add("read", "r", device="tcp", table="holding", start=198, size=125, image="%IW100",
            policy="trigger", trigger="%QX1.0", done="%IX1.0", error="%IX1.1", status="%IW11",
            length="%QW61", address="%QW62", status_first=3)
    cfg.add("write", "w", device="rtu", table="holding", start=10, size=123, image="%QW100",
            policy="trigger", trigger="%QX1.1", done="%IX1.2", error="%IX1.3", status="%IW21",
            length="%QW1", address="%QW63")
    text = cfg.text()
    assert check(text) == (0, "")
    back = model.read(text)
    assert [(s.kind, s.name, s.keys) for s in back.sections] == \
        [(s.kind, s.name, s.keys) for s in cfg.sections]
    assert back.text() == text
    for kind, keys in model.KEYS.items():        # every key of plcrt's is in it
        assert set().union(*(s.keys for s in back.of_kind(kind))) == set(keys), kind


# the grammar's rejects: the line plcrt names, and the reader's message is plcrt's
REJECTS = [
    "polling_period = 1s\n",
    "[master]\ntimeout = 1s\ntimeout = 2s\n",
    "[master]\nspeed = 1\n",
    "[master]\n[master]\n",
    "[master x]\n",
    "[retain]\nperiod = 1s\n",
    "[retain]\nrequest = %QX8.0\n",
    "[slave]\nwatch = %QW5\n",
    "[device d]\nhost = h\n[devices e]\n",
    "[device d]\nhost = h\n[device d]\nhost = h\n",
    "[device d e]\nhost = h\n",
    "[device]\n",
    "[device d]\nhost = h\nserial = /dev/ttyS0\n",
    "[device d]\nunit_id = 1\n",
    "[device d]\nhost = h\nbaud = 9600\n",
    "[device d]\nserial = /dev/ttyS0\nport = 502\n",
    "[device d]\nhost = h\n[read r]\ndevice = d\nstart = 0\nsize = 1\n",
    "[device d]\nhost = h\n[write r]\ndevice = d\nstatus_first = yes\n",
    "[device d]\nhost = h\n[read r]\ndevice = d\nstart = 0\nsize = 1\nimage = %IW1\n"
    "[read r]\n",
    "[device d]\nhost = h\nport\n",
    "[device d]\nhost =\n",
    "[device d\n",
    "[device d] x\n",
    "[device " + "n" * 64 + "]\nhost = h\n",
]


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_the_reader_stops_where_plcrt_stops(compiler, check):
    for text in REJECTS:
        rc, c_err = check(text)
        assert rc == 2, text
        with pytest.raises(model.ConfigError) as e:
            model.read(text, "plc.conf")
        assert str(e.value) == c_err, text


# plcrt's messages about the grammar (the reader's); the others are about values
GRAMMAR = re.compile(r"section header must be|unknown section|takes no name|given twice|"
                     r"name missing or not made|name too long|defined twice|expected 'key = value'"
                     r"|: missing value$|outside a section|unknown key|missing key|host and serial"
                     r"|are keys of serial|port is a key of TCP|watch and watch_count go together")


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_mangled_configs_reader_and_plcrt_agree(compiler, check):
    """On mangled configs: what plcrt accepts the reader reads, and written back plcrt accepts
    it again; where plcrt stops on the grammar the reader stops with the same line; where the
    reader stops plcrt stops (perhaps earlier, on a value: plcrt also checks the values)."""
    rng = random.Random(45)
    seen = {"accepted": 0, "grammar": 0, "value": 0}
    for _ in range(150):
        text = mangle(GOOD, rng)
        if model.is_mbconfig(text.split("\0", 1)[0]):
            continue
        rc, c_err = check(text)
        try:
            cfg = model.read(text, "plc.conf")
            err = ""
        except model.ConfigError as e:
            err = str(e)
        if rc == 0:
            assert not err, (text, err)
            assert check(cfg.text()) == (0, ""), (text, cfg.text())
            seen["accepted"] += 1
        elif GRAMMAR.search(c_err):
            assert err == c_err, text
            seen["grammar"] += 1
        else:
            seen["value"] += 1
    assert seen["grammar"] >= 30 and seen["value"] >= 10, seen


def project_configs():
    """The plcrt configs of the repository (plc/, the kit's example and tests) and those the
    project's writers make (mipcosim.programs, chainprograms)."""
    from mipcosim import chainprograms, programs
    files = sorted(p for d in ("plc", "kit/example", "tests/kit/ends", "runtime_shim/fuzz")
                   for p in (REPO / d).rglob("*") if p.suffix in (".conf", ".cfg"))
    out = [(str(p.relative_to(REPO)), p.read_text()) for p in files]
    retain = programs.retain_section("x.retain", 500)
    rtu = programs.serial_keys("/dev/ttyS0")
    out += [("outstation_config", programs.outstation_config(5020, retain=retain)),
            ("outstation_config rtu", programs.outstation_config(0, serial=rtu, status_first=3,
                                                               fc23=True)),
            ("outstation_config channel", programs.outstation_config(5020, channel=True)),
            ("central_config", programs.central_config(5020, 3, retain=retain)),
            ("central_config rtu", programs.central_config(0, 2, serial=rtu, status_first=True)),
            ("central_config channel", programs.central_config(5020, 2, channel=True)),
            ("central_many_config", programs.central_many_config(5020, retain=retain)),
            ("chain out", chainprograms.outstation_soe_config(retain=retain)),
            ("chain cen", chainprograms.central_soe_config(retain=retain)),
            ("chain push", chainprograms.central_push_config())]
    return [(name, text) for name, text in out if not model.is_mbconfig(text)]


@pytest.mark.parametrize("compiler", [compiler_param("stc")])
def test_the_projects_configs_are_read_and_written_back(compiler, check):
    """Every plcrt config of the project: plcrt accepts it or says what is wrong, the reader
    the same; a config it accepts written back by the model is accepted again and reads the
    same."""
    configs = project_configs()
    assert len(configs) >= 20
    for name, text in configs:
        rc, c_err = check(text)
        try:
            cfg = model.read(text, "plc.conf")
        except model.ConfigError as e:
            assert rc == 2 and str(e) == c_err, name
            continue
        assert rc == 0 or not GRAMMAR.search(c_err), (name, c_err)
        back = model.read(cfg.text())
        assert [(s.kind, s.name, s.keys) for s in back.sections] == \
            [(s.kind, s.name, s.keys) for s in cfg.sections], name
        if rc == 0:
            assert check(cfg.text()) == (0, ""), name


def test_the_located_addresses_of_a_config():
    cfg = model.read(GOOD)
    got = [(s.name, k, line, addr, n) for s, k, line, addr, n in cfg.located()]
    assert got == [("d", "errors", 8, "%IW90", 1), ("r", "image", 14, "%IW100", 10),
                   ("w", "image", 19, "%QW100", 123), ("w", "trigger", 21, "%QX10.0", 1),
                   ("w", "done", 22, "%IX10.0", 1), ("w", "error", 23, "%IX10.1", 1),
                   ("w", "status", 24, "%IW60", 1), ("w", "length", 25, "%QW99", 1)]


def test_model_refuses_unknown_keys_when_written():
    with pytest.raises(model.ConfigError, match=r"unknown key 'speed' in \[master\]"):
        model.Config().add("master", speed="1")
    with pytest.raises(model.ConfigError, match=r"\[device\]: needs a name"):
        model.Config().add("device", host="h")


def test_durations():
    assert [model.duration_ns(v) for v in ("100ms", "2s", "500us", "10ns", "1.5s", "20", "x")] \
        == [10**8, 2 * 10**9, 500000, 10, 1_500_000_000, 20 * 10**6, None]


def test_probe_writes_a_master_section_the_model_reads():
    """mip-probe is pure Python and installs without plcharness: it keeps its own writer of
    the [master] section (sizing.plcrt_master), held to the model here."""
    from mipprobe.sizing import plcrt_master
    p = {"tTimeout_ms": 900, "uMaxRetries": 3, "tTransferTimeout_ms": 60000,
         "read_period_ms": 250, "reply_timeout_ms": 700}
    cfg = model.read(plcrt_master(p, "mip-probe 2026-11-28"))
    assert [(s.kind, s.keys) for s in cfg.sections] == \
        [("master", {"polling_period": "250ms", "timeout": "700ms"})]
