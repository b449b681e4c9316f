"""mipemu-sim: the core in virtual time, driven by a script. Deterministic, so the application's
view of a lossy link (duplicates, overwrites, never reordering) can be checked exactly."""
import json
import subprocess

import pytest

from miptest.emu import ROOT

SIM = ROOT / "build" / "emulator" / "mipemu-sim"


def sim(script, *args, check=True):
    if not SIM.exists():
        raise RuntimeError(f"{SIM} is missing: run `make` first")
    r = subprocess.run([str(SIM), *map(str, args)], input=script, capture_output=True, text=True, timeout=60)
    if check:
        assert r.returncode == 0, r.stderr
    return r


def lines(out):
    return [json.loads(x) for x in out.splitlines()]


def logger_script(records, period_s=1.0, read_every_s=0.01):
    """The MDP sends record k (counter k in its first register) every period; the outstation
    application reads status, count and the first data register every read_every_s."""
    out = []
    t = 0.0
    for k in range(1, records + 1):
        out.append(f"at {t:.3f}")
        out.append(f"mdp 1 fc16 10 {k} {k * 10} {k * 10 + 1}")
        for i in range(int(period_s / read_every_s)):
            out.append(f"at {t + (i + 1) * read_every_s:.3f}")
            out.append("trm 1 fc3 2198 3")
        t += period_s
    return "\n".join(out) + "\n"


FAST = ["--bitrate", 1000000, "--slot-gap-ms", 1]


def test_same_seed_same_bytes():
    script = logger_script(30)
    args = ["--stations", 3, "--loss-down", 0.2, "--loss-up", 0.2, "--burst", 3, *FAST]
    a = sim(script, *args, "--seed", 5).stdout
    b = sim(script, *args, "--seed", 5).stdout
    c = sim(script, *args, "--seed", 6).stdout
    assert len(a) > 10000
    assert a == b
    assert a != c


def test_application_sees_duplicates_never_reordering():
    out = lines(sim(logger_script(100), "--loss-down", 0.3, "--loss-up", 0.3, "--seed", 3, *FAST).stdout)
    seen = [x["regs"][2] for x in out if x["ev"] == "reply" and "regs" in x and x["regs"][0] & 1]
    # every record arrives, in order; repeats of a record are the duplicates of lost confirmations
    assert sorted(set(seen)) == list(range(1, 101))
    assert seen == sorted(seen)
    assert len(seen) > 100
    radio = [x for x in out if x["ev"] == "radio"]
    lost_answers_after_block = sum(
        1 for p, a in zip(radio, radio[1:])
        if p["kind"] == "poll" and p["regs"] and not p["lost"] and a["kind"] == "answer" and a["lost"])
    assert lost_answers_after_block > 0
    # each duplicate the application saw needs a lost confirmation behind it
    assert len(seen) - 100 <= lost_answers_after_block


def test_lossless_link_has_no_duplicates():
    out = lines(sim(logger_script(50), *FAST).stdout)
    seen = [x["regs"][2] for x in out if x["ev"] == "reply" and "regs" in x and x["regs"][0] & 1]
    assert seen == list(range(1, 51))


def test_overwrite_when_the_application_reads_late():
    # three records sent one second apart, read only at the end: the last one is there, once
    script = "".join(f"at {k}\nmdp 1 fc16 10 {k}\n" for k in (1, 2, 3)) + "at 4\ntrm 1 fc3 2198 3\ntrm 1 fc3 2198 3\n"
    replies = [x for x in lines(sim(script).stdout) if x["ev"] == "reply" and "regs" in x]
    assert replies[0]["regs"] == [1, 1, 3]
    assert replies[1]["regs"] == [0, 1, 3]


@pytest.mark.parametrize("script,where,what", [
    ("at 1\nat 0.5\n", "2:4", "lies before"),
    ("trm 2 fc3 2000 1\n", "1:5", "1..1"),
    ("mdp 1 fc5 0 1\n", "1:7", "function code 5"),
    ("mdp 1 fc3 0\n", "1:7", "fc3 takes 2 numbers"),
    ("\n# comment\nbogus 1\n", "3:1", "unknown command 'bogus'"),
    ("at x\n", "1:4", "seconds"),
])
def test_script_errors_name_file_line_column(tmp_path, script, where, what):
    f = tmp_path / "s.txt"
    f.write_text(script)
    r = subprocess.run([str(SIM), str(f)], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2
    assert r.stderr.startswith(f"{f}:{where}: error: ")
    assert what in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("args", [["--stations", "0"], ["--loss-up", "2"], ["--bogus"], ["--burst", "0.5"],
                                  ["--seed"]])
def test_bad_options_exit_2(args):
    r = sim("", *args, check=False)
    assert r.returncode == 2
    assert r.stderr.startswith("mipemu-sim: error: ") and len(r.stderr.strip().splitlines()) == 1
