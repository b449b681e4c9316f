"""The portable wiring example of docs/wiring.md translates with stc against st_lib."""
import subprocess

from docs_helpers import REPO


def test_glue_example_translates(tmp_path):
    src = REPO / "docs" / "examples" / "glue_outstation.st"
    r = subprocess.run([str(REPO / ".venv" / "bin" / "stc"), "-I", str(REPO / "st_lib"),
                        "-o", str(tmp_path / "gen"), str(src)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "gen" / "POUS.c").exists()
