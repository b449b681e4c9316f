"""The test kit from kit/ (not installed): the scenario command, the pytest plugin, one-line
errors, the CI templates. Small counts on the fast radio; the example's own 10,000-record
scenario runs in test_kit_install.py (slow) and in the bench (kit_scenario)."""
import re
import sys
import xml.etree.ElementTree as ET

import pytest

from kit_helpers import (EXAMPLE, REPO, break_logger, ci_commands, forget_retain, kit_env, kit_pytest,
                         mipkit_cli, run)

REPO_PLC = REPO / "plc"

SMALL = """
name = "small"
[network]
radio = "fast"
loss_down = 0.1
loss_up = 0.1
seed = 4
[[plc]]
name = "outstation"
sources = ["@st_lib", "../st/FieldLogger.st", "../st/Outstation.st"]
config = "../plcrt/outstation.conf"
station = 1
set = { "%MW1" = 120, "%MW0" = 1 }
[[peer]]
name = "central"
[[fault]]
at_s = 2
restart = "outstation"
mode = "kill9"
[[fault]]
lose = { station = 1, direction = "up", record = 3, times = 2 }
[judge]
logged = "outstation:%MW10,%MW11"
delivered = "central"
records = 120
[expect]
complete_within_s = 300
no_xerror = ["outstation:%MW14"]
numbered_records = "central"
values = [{ at = "outstation:%MW12,%MW13", equals = 120 }, { at = "outstation:%MW16", equals = 0 },
          { at = "outstation:%MW10..%MW14", equals = [120, 0, 120, 0, 0] }]
"""


def scenario(project, text=SMALL, name="small.toml"):
    (project / "scenarios" / name).write_text(text)
    return project / "scenarios" / name


def junit(path):
    root = ET.parse(path).getroot()
    root = root if root.tag == "testsuite" else root.find("testsuite")   # pytest: <testsuites>
    props = {p.get("name"): p.get("value") for p in root.iter("property")}
    fails = [f.get("message") for f in root.iter("failure")]
    return int(root.get("tests")), fails, props


def test_scenario_green_and_junit(example, tmp_path):
    r = mipkit_cli([scenario(example), "--junit", tmp_path / "j.xml"], example)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "passed (6/6 expectations" in r.stdout
    tests, fails, _ = junit(tmp_path / "j.xml")
    assert (tests, fails) == (6, [])


# the first lines of a failure's report: the fault in the integrator's record numbers, and the
# diagnosis of the program's MIP_Sender (found by type) with st_lib's enum names
FAULT_7 = (r"mip-kit: fault: record 7 \(transfer 1, record 7 on the radio\): central accepted it "
           r"at (\d+\.\d{3}) s")
SENDER = r"  outstation FIELDSTATION\.SND \(MIP_Sender\): eState=MIP_SND_\w+ eWaitReason=MIP_WAIT_\w+ " \
         r"wWaitFor=\d+ eErrorId=MIP_ERR_\w+ \(since \d+\.\d{3} s\)"


def report_head(lines, first):
    """The report's lines from the one that matches `first` on (it must be there)."""
    i = next((k for k, l in enumerate(lines) if re.fullmatch(first, l)), None)
    assert i is not None, "\n".join(lines)
    return lines[i:]


def failing_scenario(example, tmp_path, first, fault):
    """The scenario on a broken variant, JUnit to tmp_path/results/j.xml: exit 1, its first line
    `first`, then the fault (a regex) and the blocks at the fault; returns (the run, its lines)."""
    r = mipkit_cli([scenario(example), "--junit", tmp_path / "results" / "j.xml"], example)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == first, r.stdout
    assert re.fullmatch(fault, lines[1]), r.stdout
    assert re.fullmatch(r"mip-kit: the blocks at the fault \(\d+\.\d{3} s\):", lines[2]), r.stdout
    return r, lines


def test_scenario_broken_variant_names_the_record_and_attaches_the_diagram(example, tmp_path):
    break_logger(example)
    r, lines = failing_scenario(example, tmp_path, "FAIL numbered records at central: record 7: its "
                                "registers say record 17 (first words [17, 0, 21, 28])", FAULT_7)
    assert re.fullmatch(SENDER, lines[3]), r.stdout
    tests, fails, props = junit(tmp_path / "results" / "j.xml")
    assert fails == ["record 7: its registers say record 17 (first words [17, 0, 21, 28])"], fails
    svg = props.get("mip_diagram")
    # next to the JUnit file (the templates' results/), centred on the fault's moment
    assert svg == str(tmp_path / "results" / "mip-kit-small" / "sequence-diagram.svg")
    text = open(svg).read()
    assert text.startswith("<svg") and "FC16 write" in text
    # the fault and the sender's wait drawn at its moment
    assert ">fault: record 7<" in text and re.search(r">SND: MIP_WAIT_\w+, wWaitFor=\d+<", text)
    t = float(re.fullmatch(FAULT_7, lines[1]).group(1))
    m = re.search(r"(\d+\.\d{3}) s \.\. (\d+\.\d{3}) s of virtual time", text)
    assert m and float(m.group(1)) <= t <= float(m.group(2)), m
    # the readable trace marks the telegram that carried record 7, times in s, polls folded
    around = r.stdout[r.stdout.index("---- radio and Modbus around the fault"):]
    assert re.search(rf" {t:.3f} s  radio station 1 -> MDP: answer, block \[0\]=7 \(9 registers\)"
                     r"   <- the fault", around), around
    assert "empty polls/answers" in around and '"t":' not in around


# the broken variant without the [retain] section: the sender waits for a snapshot forever
FAULT_1 = r"mip-kit: fault: record 1: never reached central \(it accepted 0 records\)"
SNAPSHOT = r"  outstation FIELDSTATION\.SND \(MIP_Sender\): eState=MIP_SND_\w+ " \
           r"eWaitReason=MIP_WAIT_SNAPSHOT wWaitFor=1 eErrorId=MIP_ERR_NONE \(since \d+\.\d{3} s\)"


def test_scenario_forgotten_retain_section_names_the_wait_for_a_snapshot(example, tmp_path):
    forget_retain(example)
    r, lines = failing_scenario(example, tmp_path, "FAIL complete within 300 s (delivered = logged): "
                                "not complete within 300 s: judge logged 120, delivered 0", FAULT_1)
    assert re.fullmatch(SNAPSHOT, lines[3]), r.stdout
    assert lines[4].startswith("    MIP_WAIT_SNAPSHOT: with xRetained := TRUE the block waits") and \
        "[retain] section" in lines[4], r.stdout
    # docs/test-kit.md shows these lines ("When a test fails")
    doc = (REPO / "docs" / "test-kit.md").read_text()
    shown = re.search(r"## When a test fails\n.*?```text\n(.*?)```", doc, re.S).group(1).splitlines()
    assert shown[:7] == lines[:7], "\n".join(lines[:8])
    assert re.sub(r": \S+/results/", ": results/", lines[7]) == shown[7], lines[7]
    svg = (tmp_path / "results" / "mip-kit-small" / "sequence-diagram.svg").read_text()
    assert ">fault: record 1<" in svg and ">SND: MIP_WAIT_SNAPSHOT, wWaitFor=1<" in svg
    # the JUnit failure carries the same lines
    root = ET.parse(tmp_path / "results" / "j.xml").getroot()
    text = next(f.text for f in root.iter("failure"))
    assert "eWaitReason=MIP_WAIT_SNAPSHOT" in text and "record 1: never reached central" in text


def test_plugin_forgotten_retain_section_names_the_wait_for_a_snapshot(example, tmp_path):
    """The example's own tests (tests/test_outstation.py) on the broken variant."""
    forget_retain(example)
    r = kit_pytest(["-k", "kill9"], example, tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 1, out
    head = out[out.index("_ test_kill9_and_lost_answers _"):].splitlines()[1:5]
    assert re.fullmatch(FAULT_1, head[0]), out
    assert re.fullmatch(r"mip-kit: the blocks at the fault \(\d+\.\d{3} s\):", head[1]), out
    assert re.fullmatch(SNAPSHOT, head[2]), out
    assert head[3].startswith("    MIP_WAIT_SNAPSHOT: "), out
    svg = example / "results" / "mip-kit" / "tests_test_outstation.py_test_kill9_and_lost_answers" / \
        "net1" / "sequence-diagram.svg"
    assert svg.read_text().startswith("<svg")


SUMMARY = (r"summary: small{tag}: complete at \d+\.\d{{3}} s; 120 records delivered; \d+ records "
           r"retransmitted by the blocks; radio lost [1-9]\d* of \d+ telegrams down, [1-9]\d* of \d+ up; "
           r"scripted: lose up record 3 at station 1 fired {fired}, kill9 restart of outstation at "
           r"2 s fired")


def test_scenario_summary_line(example):
    r = mipkit_cli([scenario(example)], example)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = [l for l in r.stdout.splitlines() if l.startswith("summary: ")]
    assert len(lines) == 1 and re.fullmatch(SUMMARY.format(tag="", fired=r"2 of 2"), lines[0]), r.stdout
    # a scripted loss that never matches says so
    text = SMALL.replace("record = 3, times = 2", "record = 999, times = 2")
    r = mipkit_cli([scenario(example, text)], example)
    assert re.search(SUMMARY.format(tag="", fired="0 of 2").replace("record 3", "record 999"),
                     r.stdout), r.stdout


def test_scenario_seed_sweep_and_named_expectations(example, tmp_path):
    text = SMALL.replace("seed = 4", "seeds = [4, 5]").replace(
        '{ at = "outstation:%MW16", equals = 0 }',
        '{ name = "no failed transfer", at = "outstation:%MW16", equals = 0 }')
    r = mipkit_cli([scenario(example, text), "--junit", tmp_path / "j.xml"], example)
    assert r.returncode == 0, r.stdout + r.stderr
    for seed in (4, 5):
        assert re.search("^" + SUMMARY.format(tag=rf" \[seed {seed}\]", fired="2 of 2") + "$",
                         r.stdout, re.M), r.stdout
    assert "passed (12/12 expectations" in r.stdout
    root = ET.parse(tmp_path / "j.xml").getroot()
    names = [tc.get("name") for tc in root.iter("testcase")]
    assert "no failed transfer [seed 4]" in names and "no failed transfer [seed 5]" in names, names
    # a range; and the seeds differ (the radio's losses)
    r = mipkit_cli([scenario(example, SMALL.replace("seed = 4", 'seeds = "1..3"'))], example)
    sums = re.findall(r"^summary: small \[seed (\d)\]: .*radio lost (\d+) of", r.stdout, re.M)
    assert [s for s, _ in sums] == ["1", "2", "3"] and len({n for _, n in sums}) == 3, r.stdout


def test_scenario_bad_seeds_is_one_line(example):
    line = one_line_failure(mipkit_cli([scenario(example, SMALL.replace("seed = 4", 'seeds = "3-1"'))],
                                       example))
    assert line.endswith("""network.seeds = '3-1': a list of seeds ([1, 2, 3]) or a range ("1..60")"""), line


def test_scenario_judge_catches_a_lost_record(example, tmp_path):
    """records delivered = records logged is really compared: a judge that counts one more
    than was logged (the high word taken as the low one) is red."""
    text = SMALL.replace('logged = "outstation:%MW10,%MW11"', 'logged = "outstation:%MW10,%MW10"')
    text = text.replace("equals = [120, 0, 120, 0, 0]", "equals = [120, 0, 119, 0, 0]")
    r = mipkit_cli([scenario(example, text), "--junit", tmp_path / "j.xml"], example)
    assert r.returncode == 1
    assert "not complete within 300 s: judge logged" in r.stdout
    assert "FAIL value outstation:%MW10..%MW14: outstation:%MW10..%MW14 = [120, 0, 120, 0, 0], " \
           "want [120, 0, 119, 0, 0]" in r.stdout


def one_line_failure(r):
    lines = [l for l in (r.stdout + r.stderr).splitlines() if l.startswith("FAIL")]
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert len(lines) == 1, r.stdout + r.stderr
    return lines[0]


def test_unknown_scenario_key_is_one_line(example):
    line = one_line_failure(mipkit_cli([scenario(example, SMALL.replace("seed = 4", "sead = 4"))],
                                       example))
    assert "unknown key 'network.sead'" in line


def test_unknown_station_is_one_line(example):
    line = one_line_failure(mipkit_cli([scenario(example, SMALL.replace("station = 1\nset", "station = 3\nset"))],
                                       example))
    assert "station 3: the network has stations 1..1 and the mdp" in line


def test_program_that_does_not_compile_names_file_line_col(example):
    f = example / "st" / "FieldLogger.st"
    f.write_text(f.read_text().replace("  uChunkLen := 8;", "  uChunkLen := 8 +;"))
    line = one_line_failure(mipkit_cli([scenario(example)], example))
    assert re.search(r"FieldLogger\.st:\d+:\d+: error", line), line


def test_config_mapping_an_undeclared_address_is_one_line(example):
    conf = example / "plcrt" / "outstation.conf"
    conf.write_text(conf.read_text().replace("done = %IX1.0", "done = %IX5.0"))
    line = one_line_failure(mipkit_cli([scenario(example)], example))
    assert re.search(r"outstation\.conf:\d+: error: done = %IX5\.0: the program does not declare %IX5\.0", line), line


PLUGIN_TEST = '''
from pathlib import Path
from mipkit import assert_records
HERE = Path(__file__).resolve().parent.parent

def expected(n):
    return [n % 65536, n // 65536] + [(n * k) % 65536 for k in range(3, 9)]

def test_readout(mip_network, mip_st_lib):
    net = mip_network(radio="fast", loss_up=0.1, seed=2)
    out = net.plc("outstation", mip_st_lib + [HERE / "st/FieldLogger.st", HERE / "st/Outstation.st"],
                  HERE / "plcrt/outstation.conf", at=1)
    central = net.peer("central")
    out["%MW1"], out["%MW0"] = 40, 1
    net.run_for(1)
    out.restart("warm")
    assert net.run_until(lambda: len(central.records) == out["%MW10"] == 40, within_s=120)
    assert_records(central.records, expected)

def test_unknown_station(mip_network, mip_st_lib):
    net = mip_network()
    net.peer("central", at=2)
'''


def test_plugin_green_red_and_one_line_errors(example, tmp_path):
    (example / "tests" / "test_plugin_user.py").write_text(PLUGIN_TEST)
    args = [sys.executable, "-m", "pytest", "-p", "mipkit.plugin", "-p", "no:cacheprovider",
            "-q", "tests/test_plugin_user.py", f"--junitxml={tmp_path / 'p.xml'}",
            f"--basetemp={tmp_path / 'bt'}"]
    r = run(args, example, kit_env())
    out = r.stdout + r.stderr
    assert r.returncode == 1, out            # test_unknown_station fails on purpose
    assert "1 passed" in out and "1 failed" in out, out
    # a KitError fails the test with its one line, no traceback
    m = re.search(r"_+ test_unknown_station _+\n(.*?)\n(?:-|=)", out, re.S)
    assert m and m.group(1).strip() == "station 2: the network has stations 1..1 and the mdp", out
    # the broken variant: the failure names record 7 and the report carries the diagram
    break_logger(example)
    r = run(args[:-2] + ["-k", "readout", f"--junitxml={tmp_path / 'b.xml'}",
                         f"--basetemp={tmp_path / 'bt2'}"], example, kit_env())
    out = r.stdout + r.stderr
    assert r.returncode == 1, out
    assert "AssertionError: record 7: got [17, 0, 21, 28, 35, 42, 49, 56], want [7, 0, 21, 28, 35, 42, 49, 56]" in out
    # the report's first lines: the fault, the record, the blocks' diagnosis
    head = out[out.index("_ test_readout _"):].splitlines()[1:5]
    assert re.fullmatch(FAULT_7, head[0]), out
    assert re.fullmatch(r"mip-kit: the blocks at the fault \(\d+\.\d{3} s\):", head[1]), out
    assert re.fullmatch(SENDER, head[2]), out
    assert re.fullmatch(r"mip-kit: the blocks at the end \(\d+\.\d{3} s\):", head[3]), out
    assert "mip-kit network 1: radio and Modbus around the fault" in out
    _, fails, props = junit(tmp_path / "b.xml")
    # under the project's results/ (the CI templates' artifact), one folder per test
    res = example / "results" / "mip-kit" / "tests_test_plugin_user.py_test_readout" / "net1"
    assert props["mip_diagram"] == str(res / "sequence-diagram.svg")
    assert open(props["mip_diagram"]).read().startswith("<svg")
    assert props["mip_trace"].endswith(".jsonl.gz") and props["mip_fault"].startswith("record 7")
    assert not list((example / "results").rglob("*.so"))


def test_passing_run_leaves_only_the_junit_files_in_results(example, tmp_path):
    """The templates' commands (the project's tests, a scenario) on a passing project: results/
    (what CI uploads) holds the JUnit files and nothing else: no build products, no trace,
    under 50 KB; pytest's temporary folders keep under 5 MB (each test's network folder, its
    builds and whole trace, is removed after it)."""
    r = kit_pytest(["--junitxml=results/pytest.xml"], example, tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    r = mipkit_cli([scenario(example), "--junit", "results/scenario.xml"], example)
    assert r.returncode == 0, r.stdout + r.stderr
    files = [p for p in (example / "results").rglob("*") if p.is_file()]
    assert sorted(p.name for p in files) == ["pytest.xml", "scenario.xml"], files
    size = sum(p.stat().st_size for p in files)
    assert size < 50_000, f"results/ holds {size} bytes"
    left = sum(p.stat().st_size for p in (tmp_path / "bt").rglob("*") if p.is_file())
    assert left < 5_000_000, f"pytest's temporary folders keep {left} bytes"


def test_ci_templates_run_the_same_commands():
    gitlab, github = ci_commands(EXAMPLE)
    assert gitlab and gitlab == github
    assert gitlab[1] == '.venv/bin/pip install "$MIP_KIT"'
    assert any(c.startswith(".venv/bin/mip-kit scenarios/readout.toml") for c in gitlab)


def test_ci_templates_fetch_the_submodule_the_kit_comes_from():
    """MIP_KIT points into a git submodule of the project: GitLab fetches submodules only with
    GIT_SUBMODULE_STRATEGY (the template lacked it: pip found no kit), GitHub's checkout only
    with submodules: true."""
    gl = (EXAMPLE / ".gitlab-ci.yml").read_text()
    gh = (EXAMPLE / ".github" / "workflows" / "sim-tests.yml").read_text()
    assert re.search(r'MIP_KIT: "\$CI_PROJECT_DIR/', gl) and "github.workspace }}/" in gh
    assert re.search(r"^\s+GIT_SUBMODULE_STRATEGY: (normal|recursive)\b", gl, re.M), gl
    assert re.search(r"uses: actions/checkout@v\d+\n\s+with:\n\s+submodules: (true|recursive)", gh)


def test_plc_at_the_mdp_with_a_peer_outstation(tmp_path):
    """A soft-PLC attached to the MDP-810 (this repository's central program and config, as a
    user's would be) reads out a note-following peer at station 2 of a two-station network."""
    from mipcosim import programs as L
    from mipkit import Net
    conf = tmp_path / "central.conf"
    conf.write_text(L.central_config(502, 2))
    records = [[n, 100 + n, 200 + n] for n in range(1, 8)]
    with Net(tmp_path / "net", 2, radio="fast", loss_down=0.2, seed=9) as net:
        cen = net.plc("central", L.program_sources("central", False), conf, at="mdp")
        peer = net.peer("outstation", at=2, records=records)
        for i, w in enumerate(L.Params(records=7, payload=3, station=0).words()):
            cen[f"%MW{i}"] = w
        assert net.run_until(lambda: peer.done, within_s=120)
        assert net.stats(2)["lost_down"] > 0 and net.stats(1)["blocks_up"] == 0
        assert cen["CENTRAL.RCV2.UDIRECORDS"] == 7


def test_matiec_builds_the_example_when_iec2c_is_on_path(example, tmp_path):
    """The same scenario with the reference compiler (iec2c on PATH); stc is the default."""
    from plcharness.build import matiec_available
    if not matiec_available():
        import pytest
        pytest.skip("matiec (iec2c) is not on PATH; it is in no package registry")
    r = mipkit_cli([scenario(example), "--compiler", "matiec", "--junit", tmp_path / "j.xml"], example)
    assert r.returncode == 0, r.stdout + r.stderr


def _cold_restart_run(tmp_path, lenient):
    from mipkit import Net
    src = [EXAMPLE / "st" / "FieldLogger.st", EXAMPLE / "st" / "Outstation.st"]
    from mipcosim import programs as L
    lib = L.lib_sources()
    net = Net(tmp_path / ("lenient" if lenient else "strict"), radio="fast", seed=1)
    out = net.plc("outstation", lib + src, EXAMPLE / "plcrt" / "outstation.conf", at=1)
    central = net.peer("central", lenient=lenient)
    out["%MW1"], out["%MW0"] = 250, 1
    net.run_for(2)                          # in the middle of the first transfer of 100
    mid = len(central.records)
    assert 0 < mid < 100
    out.restart("cold")                     # all state lost: the log starts again at record 1
    out["%MW1"], out["%MW0"] = 250, 1
    errors = []
    done = net.run_until(lambda: errors.append(out["%MW14"]) or out["%MW12"] == 250, within_s=60)
    return net, central, mid, done, errors


def out_failed(net):
    return net["outstation"]["%MW16"]


def test_cold_restart_lenient_peer_takes_the_new_transfer(tmp_path):
    net, central, mid, done, errors = _cold_restart_run(tmp_path, lenient=True)
    with net:
        assert done and not any(errors)
        # the open transfer (what arrived before the restart, and a record still on its way
        # in the modem) is abandoned; the new log arrives whole
        abandoned = central.peer.receiver.abandoned
        assert len(abandoned) == 1 and mid <= len(abandoned[0]) <= mid + 1
        assert [r[0] for r in central.records] == list(range(1, 251))


def test_cold_restart_strict_peer_refuses_it(tmp_path):
    net, central, mid, done, errors = _cold_restart_run(tmp_path, lenient=False)
    with net:
        # the strict peer answers record 1 with its old acknowledgement: nothing more arrives,
        # and MIP_Sender ends each try in MIP_ERR_PEER_OUT_OF_STEP after 3 x tTimeout (P11)
        assert not done and mid <= len(central.records) <= mid + 1
        assert central.peer.receiver.unexpected > 0
        assert any(errors) and out_failed(net) >= 2


def test_openplc_mbconfig_and_static_mode(tmp_path):
    """An OpenPLC mbconfig.cfg (cyclic polling, static MIP mode: this repository's OpenPLC
    outstation, as a user's would be) on a static network, the peer writing static blocks."""
    from mipcosim import programs as L
    from mipkit import Net, assert_records
    with Net(tmp_path / "net", 1, radio="fast", static=True, static_registers=123, seed=2) as net:
        out = net.plc("outstation", L.program_sources("outstation", False),
                      REPO_PLC / "openplc" / "outstation-mbconfig.cfg", at=1)
        central = net.peer("central", static_registers=123)
        for i, w in enumerate(L.Params(records=20, payload=16, station=1, static=True,
                                       cyclic=True, chunk=123).words()):
            out[f"%MW{i}"] = w
        assert net.run_until(lambda: central.transfers == 1, within_s=200)
        assert assert_records(central.records, lambda n: [L.log_value(n, j, 1, 1)
                                                          for j in range(16)]) == 20
        assert all(len(r) == 122 for r in central.records)     # static blocks, padded


def test_kit_pins_agree_with_requirements():
    """The kit's build backend and runtime dependencies are the versions requirements.txt pins."""
    import tomllib
    pins = dict(l.split("==") for l in (REPO / "requirements.txt").read_text().splitlines()
                if "==" in l and not l.startswith("#"))
    meta = tomllib.loads((REPO / "kit" / "pyproject.toml").read_text())
    for req in meta["build-system"]["requires"] + meta["project"]["dependencies"]:
        if "==" in req:
            name, ver = req.split("==")
            assert pins.get(name) == ver, f"kit/pyproject.toml {req}, requirements.txt {pins.get(name)}"
    named = {r.split("==")[0].split(">=")[0] for r in meta["build-system"]["requires"] + meta["project"]["dependencies"]}
    assert {"setuptools", "wheel", "lark", "pymodbus"} <= named


def _needs_iec2c():
    from plcharness.build import matiec_available
    return pytest.mark.skipif(not matiec_available(),
                              reason="matiec (iec2c) is not on PATH; it is in no package registry")


@pytest.mark.parametrize("compiler", ["stc", pytest.param("matiec", marks=_needs_iec2c())])
def test_restarts_say_whether_retain_was_restored(tmp_path, compiler):
    """A matiec build keeps its RETAIN variables as an stc build does (the variables matiec
    marks retained, and the arrays it cannot mark)."""
    from mipcosim import programs as L
    from mipkit import Net
    lib = L.lib_sources()
    with Net(tmp_path / "net", radio="fast", compiler=compiler) as net:
        out = net.plc("outstation", lib + [EXAMPLE / "st" / "FieldLogger.st", EXAMPLE / "st" / "Outstation.st"],
                      EXAMPLE / "plcrt" / "outstation.conf", at=1, retain_period_ms=200)
        assert out.result.compiler == compiler
        net.peer("central")
        out["%MW1"], out["%MW0"] = 30, 1
        out.restart("kill9", down_s=0.1)   # before the first periodic snapshot: cold
        out["%MW1"], out["%MW0"] = 30, 1     # so the operator starts it again
        net.run_for(1)
        out.restart("kill9", down_s=0.1)
        out.restart("warm", down_s=0.1)
        net.run_for(0.5)
        assert out["%MW10"] == 30           # warm: the logger (RETAIN) still has its records
        out.restart("cold", down_s=0.1)
        net.run_for(0.5)
        assert out["%MW10"] == 0            # cold: log and parameters are gone
        assert [(m, r) for _, m, r in out.restarts] == [("kill9", False), ("kill9", True),
                                                         ("warm", True), ("cold", False)]


def test_wheel_carries_what_the_kit_needs_and_the_checkout_stays_clean(tmp_path):
    """pip's build of kit/ (offline: --no-build-isolation with this venv's setuptools): the
    repository's packages, the runtime's C sources, libmipcosim.so, st_lib, the diagram
    generator, the entry points; no object files; nothing written into kit/."""
    import zipfile
    before = sorted(p.relative_to(REPO) for p in (REPO / "kit").rglob("*") if "__pycache__" not in p.parts)
    r = run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
             "--no-index", "-w", tmp_path, REPO / "kit"], tmp_path)
    assert r.returncode == 0, r.stderr
    after = sorted(p.relative_to(REPO) for p in (REPO / "kit").rglob("*") if "__pycache__" not in p.parts)
    assert after == before
    (whl,) = tmp_path.glob("mip_logger_kit-*.whl")
    names = zipfile.ZipFile(whl).namelist()
    for want in ["stc/cli.py", "stc/st.lark", "plcharness/build.py",
                 "plcharness/_runtime/src/plcrt_main.c", "plcharness/_runtime/include/plcrt.h",
                 "mipcosim/_lib/libmipcosim.so", "mipcosim/_st_lib/core/MIP_Sender.st",
                 "mippeer/peer.py", "mipprobe/cli.py", "mipprobe/regmap.py", "mipkit/plugin.py",
                 "mipdocs/seqdiag.py", "mipdocs/__init__.py"]:
        assert want in names, want
    assert not [n for n in names if n.endswith((".o", ".pyc"))]
    ep = next(n for n in names if n.endswith("entry_points.txt"))
    text = zipfile.ZipFile(whl).read(ep).decode()
    assert "[pytest11]\nmipkit = mipkit.plugin" in text and "mip-kit = mipkit.scenario:main" in text
    assert "mip-probe = mipprobe.cli:main" in text      # issue 48: the commissioning tool


def test_one_record_at_a_time_passes_assert_records_against_the_note_peer(tmp_path):
    """Issue 39: records logged one every 2 s leave each transfer one record, which MIP_Sender
    sends as record 1 and an empty 16#FFFF (P5). peer.records held an empty payload for every
    such 16#FFFF and assert_records failed ("record 2: got [], want [...]"); an empty record
    ends a transfer but is no record, for the note peer as for MIP_Receiver."""
    from mipkit import Net, assert_records
    from mipcosim import programs as L
    lib = L.lib_sources()
    src = [EXAMPLE / "st" / "FieldLogger.st", EXAMPLE / "st" / "Outstation.st"]
    with Net(tmp_path, radio="fast", seed=3) as net:
        out = net.plc("outstation", lib + src, EXAMPLE / "plcrt" / "outstation.conf", at=1)
        central = net.peer("central")
        out["%MW1"], out["%MW3"], out["%MW0"] = 5, 2000, 1
        assert net.run_until(lambda: out["%MW12"] == 5, within_s=60)
        net.run_for(1)
        assert central.transfers == 5
        assert assert_records(central.records, lambda n: [n % 65536, n // 65536]
                              + [(n * k) % 65536 for k in range(3, 9)]) == 5


def test_delivered_taps_the_integrators_own_central(tmp_path):
    """Issue 39: what the integrator's own central (here this repository's, with four
    MIP_Receiver instances) delivered, record by record, without glue in the program: found by
    type, read after every scan. The outstation logs one record every 2 s, so every transfer
    ends with an empty 16#FFFF, which is not delivered; a kill -9 of the central rolls its
    receivers back, and what they delivered after the snapshot comes again, once."""
    from mipcosim import programs as L
    from mipkit import KitError, Net, assert_records
    conf = tmp_path / "central.conf"
    conf.write_text(L.central_config(502, 1, retain=L.retain_section(tmp_path / "c.retain", 1000)))
    lib = L.lib_sources()
    src = [EXAMPLE / "st" / "FieldLogger.st", EXAMPLE / "st" / "Outstation.st"]
    want = lambda n: [n % 65536, n // 65536] + [(n * k) % 65536 for k in range(3, 9)]  # noqa: E731
    with Net(tmp_path / "net", 1, radio="fast", loss_up=0.2, seed=4) as net:
        cen = net.plc("central", L.program_sources("central", False), conf, at="mdp")
        out = net.plc("outstation", lib + src, EXAMPLE / "plcrt" / "outstation.conf", at=1)
        for i, w in enumerate(L.Params(records=0, station=0, retain=True).words()):
            cen[f"%MW{i}"] = w
        out["%MW1"], out["%MW3"], out["%MW0"] = 8, 1500, 1
        assert [r.split(".")[-1] for r in cen.receivers] == ["RCV1", "RCV2", "RCV3", "RCV4"]
        with pytest.raises(KitError, match="has 4 MIP_Receiver instances .*name one"):
            cen.delivered()
        assert net.run_until(lambda: len(cen.delivered("RCV1")) >= 3, within_s=60)
        cen.restart("kill9")
        assert net.run_until(lambda: out["%MW12"] == 8, within_s=120)
        net.run_for(2)
        assert assert_records(cen.delivered("rcv1"), want) == 8
        assert cen.transfers_received("RCV1") == 8 and cen.delivered("RCV2") == []
