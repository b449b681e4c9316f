"""The training tool mipsim (docs/exercises.md): a clean transfer completes with exact data, a
restart is reported the way the exercises say, bad options are one line with exit status 2."""
from docs_helpers import tool


def test_clean_transfer_completes():
    r = tool("mipsim", "--records", 3, "--timeout-ms", 500)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith("mipsim: complete after ")
    assert "records acknowledged=3 retransmissions=0" in r.stdout
    assert "records delivered=3 duplicates=0 unexpected=0 failed transfers=0" in r.stdout


def test_outstation_restart_is_reported_by_the_central(tmp_path):
    trace = tmp_path / "t.jsonl"
    r = tool("mipsim", "--records", 4, "--restart", "outstation", "--restart-at-ms", 1000,
             "--trace", trace)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "errors=['MIP_ERR_SENDER_RESET']" in r.stdout
    assert '"what":"restart"' in trace.read_text()


def test_same_options_same_trace(tmp_path):
    for k in (1, 2):
        r = tool("mipsim", "--records", 2, "--loss-up", 0.3, "--seed", 4, "--trace",
                 tmp_path / f"{k}.jsonl")
        assert r.returncode == 0, r.stdout + r.stderr
    assert (tmp_path / "1.jsonl").read_bytes() == (tmp_path / "2.jsonl").read_bytes()


def test_bad_option_is_one_line():
    r = tool("mipsim", "--loss-up", 1.5)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1] == "mipsim: error: --loss-up must be 0..1"
    assert "Traceback" not in r.stderr
