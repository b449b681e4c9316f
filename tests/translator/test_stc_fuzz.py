"""Short, seeded run of the front-end fuzzer (translator/fuzz/fuzz_stc.py): mutated corpus files
must never make stc raise, and what it accepts must compile with -Werror."""
import os
import sys

import stc_harness as H

sys.path.insert(0, os.path.join(H.ROOT, "translator", "fuzz"))
import fuzz_stc  # noqa: E402


def test_fuzz_seeded_short(tmp_path, capsys):
    rc = fuzz_stc.main(["--cases", "400", "--seed", "20261122", "--findings", str(tmp_path), "--quiet"])
    out = capsys.readouterr().out
    findings = sorted(os.listdir(tmp_path))
    details = ""
    for f in findings[:4]:
        if f.endswith(".txt"):
            details += (tmp_path / f).read_text()[:1500]
    assert rc == 0 and not findings, f"{out}\n{details}"
    assert "400 cases" in out
