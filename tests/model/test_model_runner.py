"""model/run.py, the spin model of the record protocol: the runner's verdicts a developer sees.
The full matrix runs in `make model-check` (part of `make test`); here only what proves the
checker can fail: a known silent hang is found and shown as a trace, and a wrong expectation
or a bad argument ends non-zero with one line."""
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
RUN = ROOT / "model" / "run.py"

pytestmark = pytest.mark.skipif(shutil.which("spin") is None,
                                reason="spin is not installed (Debian package 'spin', see .ci/apt-packages.txt)")


def run(*args, tmp_path):
    return subprocess.run([sys.executable, str(RUN), "--work", str(tmp_path / "w"), *args],
                          capture_output=True, text=True, timeout=600)


def test_silent_hang_of_two_note_peers_is_found_with_its_trace(tmp_path):
    r = run("--exact", "-k", "note-note-strict/spont/up+rst-rcv", "--trace-dir", str(tmp_path / "t"), tmp_path=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    row = [ln for ln in r.stdout.splitlines() if ln.startswith("note-note-strict/spont/up+rst-rcv")]
    assert len(row) == 1 and "known weakness reproduced: progress" in row[0]
    states, depth = row[0].split()[1:3]
    assert int(states) > 1000 and int(depth) > 10
    trace = (tmp_path / "t" / "note_note_strict_spont_up_rst_rcv.txt").read_text()
    assert "receiver PLC restarts" in trace
    assert "repeats forever" in trace
    assert r.stdout.splitlines()[-1] == "model: 1 passed, 0 failed"


def test_a_violation_where_all_must_hold_fails_the_run(tmp_path):
    # two note peers without restarts must hold; adding a receiver restart through -D makes
    # the strict note receiver hang, and a configuration that must hold then fails the run
    r = run("--exact", "-k", "note-note-strict/spont/up", "-D", "RST_R=1", "-D", "NT=1", tmp_path=tmp_path)
    assert r.returncode == 1
    row = [ln for ln in r.stdout.splitlines() if ln.startswith("note-note-strict/spont/up ")]
    assert "VIOLATED progress" in row[0]
    assert "--- from here the run repeats forever (no progress) ---" in r.stdout


def test_unknown_configuration_is_one_line(tmp_path):
    r = run("-k", "no-such-configuration", tmp_path=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "no configuration matches" in r.stderr


def test_our_sender_without_the_echo_check_mixes_transfers_after_a_restart(tmp_path):
    # P8 (the echo's check value) is what keeps a stale acknowledgement from counting after
    # our sender restarts: the model with the number alone (P8_MODE=1) must find the mix
    r = run("--exact", "-k", "ours-ours/spont/up+rst-snd", "-D", "P8_MODE=1", tmp_path=tmp_path)
    assert r.returncode == 1
    assert "VIOLATED MIX" in r.stdout
    assert "sender PLC restarts" in r.stdout


def test_our_link_without_the_own_modem_confirmation_mixes_transfers_after_a_restart(tmp_path):
    # bidirectional layout: no echo; P9 (count an acknowledgement only after the own modem
    # confirmed the record) keeps a stale acknowledgement from counting after our restart.
    # With the number alone (P9_MODE=1) the model must find the mix.
    r = run("--exact", "-k", "bidi/ours-ours/spont/up+rst-snd", "-D", "P9_MODE=1", tmp_path=tmp_path)
    assert r.returncode == 1, r.stdout
    assert "VIOLATED MIX" in r.stdout
    assert "sender PLC restarts" in r.stdout


def test_a_violation_after_the_sender_finished_is_found_by_the_progress_search(tmp_path):
    # "holds" is proven by one search, pan -a -f: its claim (env.pml) goes on after the sender
    # finished, so the assertions of every later state are checked too. The idle link's
    # record 0 sent before a snapshot holds it (IDLEGATE=0, a part of W4 that acts only after
    # the transfer) lets a rollback repeat 16#FFFF: a claim that stops at the goal (spin's
    # own from the ltl formula) reports "holds" here.
    r = run("--exact", "-k", "warm/bidi/ours-ours/spont/up+wrst-snd", "-D", "IDLEGATE=0",
            tmp_path=tmp_path)
    assert r.returncode == 1, r.stdout
    row = [ln for ln in r.stdout.splitlines() if ln.startswith("warm/bidi/ours-ours/spont/up+wrst-snd ")]
    assert len(row) == 1 and row[0].split()[4] == "liveness", row
    assert "VIOLATED WARMFAIL" in row[0]
    assert "outstation(TRM) PLC writes [0] for the other stream" in r.stdout   # the idle record 0
    assert "sender PLC warm restart" in r.stdout


@pytest.mark.slow   # two searches of 200 and 300 MB: 16 s
def test_a_bounded_configuration_searches_as_far_as_its_cap_and_says_it_is_no_proof(tmp_path):
    """make check searches the configurations of BOUNDED as far as their cap; --bounded-memlim
    sets it (make model-deep: 0, no cap). Two caps (above the 128 MB of pan's hash table): the
    smaller stores fewer states, and both
    verdicts say the search was bounded."""
    stored = {}
    for cap in (192, 288):
        r = run("--exact", "-k", "warm/win2/ours-ours/spont/up+wrst-snd", "--bounded-memlim",
                str(cap), tmp_path=tmp_path)
        assert r.returncode == 0, r.stdout + r.stderr
        row = [ln for ln in r.stdout.splitlines()
               if ln.startswith("warm/win2/ours-ours/spont/up+wrst-snd")]
        assert len(row) == 1 and "bounded: no violation in the first" in row[0], r.stdout
        assert "not a proof" in row[0]
        stored[cap] = int(row[0].split()[1])
        assert "bounded searches, not proofs" in r.stdout
    assert 0 < stored[192] < stored[288], stored


def _listed(*args, tmp_path):
    r = run("--list", *args, tmp_path=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    return {ln.split()[0] for ln in r.stdout.splitlines()}


def test_make_check_and_check_large_together_search_every_configuration_once(tmp_path):
    # make check runs --tier check, make check-large --tier large (CI runs both): no
    # configuration may fall between the two or be searched twice, and make test's quick set
    # stays in make check
    every = _listed(tmp_path=tmp_path)
    check = _listed("--tier", "check", tmp_path=tmp_path)
    large = _listed("--tier", "large", tmp_path=tmp_path)
    quick = _listed("--quick", tmp_path=tmp_path)
    assert check | large == every and not check & large
    assert quick <= check
    assert large and len(large) < len(check)
    assert any(n.startswith("warm/bidi/") for n in large)
    mk = subprocess.run(["make", "-n", "--no-print-directory", "model-check", "model-large"], cwd=ROOT,
                        capture_output=True, text=True)
    assert "--tier check" in mk.stdout and "--tier large" in mk.stdout, mk.stdout + mk.stderr
