"""The view's pages: every exercise has a "watch it" line, each preset is the run of its
exercise's own mipsim command, and the pictures of docs/view.md are the generator's."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

from mipview import session as S
from mipview import shots

REPO = Path(__file__).resolve().parents[2]
EXERCISES = (REPO / "docs" / "exercises.md").read_text()
VIEW = (REPO / "docs" / "view.md").read_text()


def sections():
    """{exercise number: its text} of docs/exercises.md (up to the solutions)."""
    body = EXERCISES[:EXERCISES.index("## Solutions")]
    parts = re.split(r"^## Exercise (\d+):", body, flags=re.M)
    return {parts[i]: parts[i + 1] for i in range(1, len(parts), 2)}


def mipsim_commands(text):
    """The options of every mipsim command in a section's blocks: [{option: value or True}]."""
    text = text.replace("\\\n", " ")
    out = []
    for m in re.finditer(r"docs/tools/mipsim\.py([^|;\n]*)", text):
        words, opts, i = shlex.split(m.group(1)), {}, 0
        while i < len(words):
            if i + 1 < len(words) and not words[i + 1].startswith("--"):
                opts[words[i]] = words[i + 1]
                i += 2
            else:
                opts[words[i]] = True
                i += 1
        out.append(opts)
    return out


def preset_options(p: S.Preset):
    """A preset as mipsim options, defaults included (the command may spell them out)."""
    return {"--records": str(p.records), "--polled": p.polled, "--loss-up": f"{p.loss_up:g}",
            "--loss-down": f"{p.loss_down:g}", "--burst": f"{p.burst:g}", "--seed": str(p.seed),
            "--timeout-ms": str(p.timeout_ms), "--restart": p.restart,
            "--restart-at-ms": str(p.restart_at_ms), "--trace": None}


DEFAULTS = preset_options(S.Preset("", ""))


def matches(cmd, p):
    """The command runs the preset's transfer: every option it gives is the preset's (a shell
    variable stands for any value), every option the preset changes is given."""
    want = preset_options(p)
    for k, v in cmd.items():
        if k == "--trace" or (isinstance(v, str) and v.startswith("$")):
            continue
        if k not in want or (want[k] != v and not (v is True and want[k] is True)):
            return False
    return all(k in cmd for k, v in want.items() if v != DEFAULTS[k])


def test_every_exercise_has_a_watch_it_line_with_its_presets():
    secs = sections()
    assert set(secs) == {str(n) for n in range(1, 10)}
    for n, text in secs.items():
        lines = [x for x in text.splitlines() if x.startswith("**Watch it**")]
        assert len(lines) == 1 and "(view.md)" in lines[0], f"exercise {n}: one watch-it line"
        named = set(re.findall(r"--preset ([\w-]+)", lines[0]))
        ours = {k for k, p in S.PRESETS.items() if p.exercise == n}
        assert named == ours, f"exercise {n}: the watch-it line names {named}, presets {ours}"
        if not ours:     # the real emulator: the view follows its trace
            trace = re.search(r"--trace (/tmp/\S+\.jsonl)", text).group(1)
            assert f"--follow {trace}" in lines[0], f"exercise {n}"


def test_each_preset_is_its_exercises_run():
    secs = sections()
    for name, p in S.PRESETS.items():
        if not p.exercise:
            continue
        cmds = mipsim_commands(secs[p.exercise])
        assert any(matches(c, p) for c in cmds), \
            f"preset {name} ({p.mipsim_args()}) is none of exercise {p.exercise}'s runs: {cmds}"


def test_the_pictures_are_the_generators():
    pictures = re.findall(r"\]\(img/(view-[\w-]+\.png)\)", VIEW)
    assert sorted(pictures) == sorted(f"view-{n}.png" for n in shots.DOCS_PRESETS)
    for name in shots.DOCS_PRESETS:
        path = REPO / "docs" / "img" / f"view-{name}.png"
        text = shots.png_text(path).get("mip-view", "")
        head, tail = shots.describe(name, 0).split(" 0 ms")
        assert re.fullmatch(re.escape(head) + r" \d+ ms" + re.escape(tail), text), \
            f"{path}: {text!r}: not from mipview.shots, or stale (make view-shots)"
        assert shots.png_size(path) == (shots.VIEWPORT["width"], shots.VIEWPORT["height"])
