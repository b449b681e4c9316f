"""Issue 39: what the kit accepted silently says so in one line: a [retain] period the test
overrides, a located address the program does not declare, a judge reference in the wrong
form, a program without CONFIGURATION; stc's portability warnings are shown (once per build);
stc's semantics are selectable."""
import re
import sys
import warnings

import pytest
from mipprograms.common import config

from kit_helpers import EXAMPLE, kit_env, kit_pytest, mipkit_cli, run
from test_kit_quick import SMALL, one_line_failure, scenario

SOURCES = [EXAMPLE / "st" / "FieldLogger.st", EXAMPLE / "st" / "Outstation.st"]
WARNING = r"Outstation\.st:\d+:\d+: warning: portability: TIME \* number differs between matiec and IEC"

PROGRAM = """PROGRAM P
VAR
  n AT %MW0 : WORD;
  s AT %MD1 : DINT;
END_VAR
VAR
  t : TIME;
END_VAR
t := T#1ms * WORD_TO_DINT(n);
s := TIME_TO_DINT(t);
END_PROGRAM
"""
CONFIG = config("P", "p0")


PERIOD = "tLogPeriod := T#1s * (WORD_TO_DINT(pLogPeriod) / 1000) + T#1ms * (WORD_TO_DINT(pLogPeriod) MOD 1000);"


def non_portable(project):
    """The example's log period computed the non-portable way (stc warns: matiec's value of
    T#1ms * 2148 is -2.147 s)."""
    f = project / "st" / "Outstation.st"
    text = f.read_text()
    assert text.count(PERIOD) == 1, "Outstation.st changed: the warning needs a new anchor"
    f.write_text(text.replace(PERIOD, "tLogPeriod := T#1ms * WORD_TO_DINT(pLogPeriod);"))


def lib():
    from mipcosim import programs as L
    return L.lib_sources()


def example_plc(net, **kw):
    return net.plc("outstation", lib() + SOURCES, kw.pop("config", EXAMPLE / "plcrt" / "outstation.conf"),
                   at=1, **kw)


def test_undeclared_address_is_one_line(tmp_path):
    from mipkit import KitError, Net
    with Net(tmp_path / "net", radio="fast") as net:
        out = example_plc(net)
        out["%MW1"] = 5                          # declared: fine
        assert out["%IW150"] == 0               # mapped by the config's read range: fine
        for do in (lambda: out["%MW99"], lambda: out.__setitem__("%MW99", 1)):
            with pytest.raises(KitError) as e:
                do()
            assert str(e.value) == ("outstation: %MW99: the program does not declare %MW99 (it "
                                    "declares %MW0..%MW3, %MW10..%MW14, %MW16): reading it gives 0, "
                                    "writing it reaches nothing")


def test_undeclared_address_in_a_scenario_is_one_line(example):
    line = one_line_failure(mipkit_cli([scenario(example, SMALL.replace('"%MW0" = 1', '"%MW0" = 1, "%MW99" = 3'))],
                                       example))
    assert line.endswith("outstation: %MW99: the program does not declare %MW99 (it declares "
                         "%MW0..%MW3, %MW10..%MW14, %MW16): reading it gives 0, writing it reaches nothing"), line


def test_delivered_in_the_wrong_form_shows_the_right_one(example):
    line = one_line_failure(mipkit_cli([scenario(example, SMALL.replace('delivered = "central"',
                                                                        'delivered = "plc:%MW20"'))], example))
    assert line == ("FAIL scenario runs: judge.delivered = 'plc:%MW20': no PLC or peer named 'plc' "
                    "(have: outstation, central); a reference is 'NAME:%MW20' (a word of PLC NAME), "
                    "'NAME:%MW20,%MW21' (two words, low and high), 'NAME:%MW20..%MW23' (a list), "
                    "'NAME:PROG.var', 'NAME:PROG.arr[0..7]' (a list), or the name of a peer, "
                    "[[unicos]] or [[scada]]"), line


def test_the_documented_delivered_form_works(example):
    """docs/test-kit.md's PLC form of judge.delivered: 'NAME:%MW12,%MW13' (here the
    outstation's own count of records read out, as an integrator's central would count)."""
    text = SMALL.replace('delivered = "central"', 'delivered = "outstation:%MW12,%MW13"')
    r = mipkit_cli([scenario(example, text)], example)
    assert r.returncode == 0, r.stdout + r.stderr
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "test-kit.md").read_text()
    assert '"plc:%MWn"' not in doc and 'delivered = "central:%MW20,%MW21"' in doc


def test_missing_configuration_is_one_line(tmp_path):
    from mipkit import KitError, Net
    src = tmp_path / "P.st"
    src.write_text(PROGRAM)
    (tmp_path / "empty.conf").write_text("")
    with Net(tmp_path / "net") as net, pytest.raises(KitError) as e:
        net.plc("p", [src], tmp_path / "empty.conf", at=1)
    assert str(e.value).startswith(f"{src}: error: no CONFIGURATION: the kit runs a program from a "
                                   "CONFIGURATION whose TASK has an INTERVAL")
    assert "common_ticktime" not in str(e.value)


def test_retain_period_of_the_config_is_used_and_an_override_said(tmp_path):
    from mipkit import KitWarning, Net
    conf = tmp_path / "outstation.conf"
    conf.write_text((EXAMPLE / "plcrt" / "outstation.conf").read_text().replace("period = 1000ms",
                                                                                  "period = 5s"))
    # the config's period: no periodic snapshot before 5 s (and the idle sender asks for none),
    # so a kill -9 at 2 s restarts cold
    with Net(tmp_path / "a", radio="fast") as net, warnings.catch_warnings():
        # no note: nothing overrides the config
        warnings.filterwarnings("error", message=r".*\[retain\]", category=KitWarning)
        out = example_plc(net, config=conf)
        net.peer("central")
        net.run_for(2)
        out.restart("kill9", down_s=0.1)
        assert [r for _, _, r in out.restarts] == [False]
    # the test's own period wins, in one line
    with Net(tmp_path / "b", radio="fast") as net:
        with pytest.warns(KitWarning) as w:
            out = example_plc(net, config=conf, retain_period_ms=200)
        notes = [str(x.message) for x in w if "[retain]" in str(x.message)]
        line = conf.read_text().splitlines().index("period = 5s") + 1
        assert notes == [f"{conf}:{line}: [retain] period = 5s is not what the kit uses for outstation: "
                         "it takes snapshots every retain_period_ms = 200"], notes
        net.peer("central")
        net.run_for(2)
        out.restart("kill9", down_s=0.1)
        assert [r for _, _, r in out.restarts] == [True]


def test_stc_warnings_once_per_build_in_mip_kit(example):
    non_portable(example)
    text = SMALL.replace("seed = 4", "seeds = [4, 5]")
    r = mipkit_cli([scenario(example, text)], example)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = [l for l in r.stdout.splitlines() if re.search(WARNING, l)]
    assert len(lines) == 1 and lines[0].startswith(f"mip-kit: {example / 'st' / 'Outstation.st'}:"), r.stdout


def test_stc_warnings_in_pytest(example, tmp_path):
    non_portable(example)
    r = kit_pytest(["-k", "kill9"], example, tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    assert re.search(r"KitWarning: \S+" + WARNING, out), out


@pytest.mark.parametrize("how", ["argument", "env"])
def test_semantics_are_selectable(tmp_path, monkeypatch, how):
    """T#1ms * 2148 is -2.147 s with matiec's values (stc's default) and 2.148 s with IEC's."""
    from mipkit import Net
    src = tmp_path / "P.st"
    src.write_text(PROGRAM + CONFIG)
    (tmp_path / "empty.conf").write_text("")
    got = {}
    for sem in ("matiec", "iec"):
        kw = {"semantics": sem}
        if how == "env":
            monkeypatch.setenv("PLCRT_SEMANTICS", sem)
            kw = {}
        with Net(tmp_path / f"net-{sem}", **kw) as net, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            p = net.plc("p", [src], tmp_path / "empty.conf", at=1)
            p["%MW0"] = 2148
            net.run_for(0.05)
            got[sem] = p["%MD1"]
    assert got == {"matiec": 2**32 - 2, "iec": 2}, got


def test_semantics_option_of_mip_kit_and_the_plugin(example):
    r = mipkit_cli([scenario(example), "--semantics", "iec"], example)
    assert r.returncode == 0, r.stdout + r.stderr
    r = mipkit_cli([scenario(example), "--semantics", "isc"], example)
    assert r.returncode == 1 and "argument --semantics: invalid choice: 'isc'" in r.stdout + r.stderr
    r = run([sys.executable, "-m", "pytest", "-p", "mipkit.plugin", "--help"], example, kit_env())
    assert "--mip-semantics" in r.stdout and "--mip-results" in r.stdout


def test_warnings_as_errors_are_one_line_too(example, tmp_path):
    """A project that makes the kit's warnings errors (-W error::mipkit.KitWarning) gets stc's
    portability warning as the test's one-line failure."""
    non_portable(example)
    r = kit_pytest(["-k", "kill9", "-W", "error::mipkit.KitWarning"], example, tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 1, out
    m = re.search(r"_+ test_kill9_and_lost_answers _+\n(.*?)\n(?:-|=)", out, re.S)
    assert m and re.fullmatch(r"\S+" + WARNING + r".*", m.group(1).strip()), out
    assert "Traceback" not in out
