"""Short, seeded run of the front-end fuzzer (translator/fuzz/fuzz_stc.py): mutated corpus files
must never make stc raise, and what it accepts must compile with -Werror."""
import os
import subprocess
import sys

import stc_harness as H

FUZZ = os.path.join(H.ROOT, "translator", "fuzz", "fuzz_stc.py")


def test_fuzz_seeded_short(tmp_path):
    p = subprocess.run([sys.executable, FUZZ, "--cases", "400", "--seed", "20261122",
                        "--findings", str(tmp_path), "--quiet"], capture_output=True, text=True,
                       timeout=600)
    rc, out = p.returncode, p.stdout + p.stderr
    findings = sorted(os.listdir(tmp_path))
    details = ""
    for f in findings[:4]:
        if f.endswith(".txt"):
            details += (tmp_path / f).read_text()[:1500]
    assert rc == 0 and not findings, f"{out}\n{details}"
    assert "400 cases" in out
