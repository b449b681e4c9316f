"""Runs the command blocks of the Markdown pages, as a reader would type them (tests/docs/).

Sybil (pinned in requirements.txt) finds the fenced blocks and runs them in order, one
namespace per page; this module only says how a block of each language is run:

- ```` ```sh ````: every logical line (a trailing backslash continues it; `#` lines are
  comments) is one command; each must exit 0. A line ending in `&` starts a background job.
- ```` ```console ````: `$ ` lines are commands (continued by `\\`), the lines after one are
  its expected output (stdout and stderr, in one stream). `...` in the expected text stands for
  anything (a line of only `...`: any number of lines); ports after `127.0.0.1:` and times
  (`1.5s`, `t=0.9s`, `seconds=1.5`, `0.36 wall s`) are normalised on both sides, and so are
  runs of blanks (mbpoll prints tabs). A command exits 0; a page that shows a failure shows
  its status (`cmd; echo "exit status $?"`). Programs that write errors to stderr unbuffered
  (mbpoll) may print them before their stdout: put `...` on both sides of such a line.
- ```` ```python ````: executed in the test's process (one namespace per page); `test_*`
  functions it defines are called (with a `tmp_path` of their own); the runtime harness's build
  cache is off meanwhile (it lives in the shared build/).

A block whose first line is `# not run by the tests: REASON` (the same words, visible on the
page) is not run; the reason must say why it cannot run here (a vendor IDE, a real modem, ...).

Why Sybil: the pages are Markdown with shell sessions and Python in one document, whose blocks
build on each other. pytest-markdown-docs runs Python blocks only; prysk (cram) runs shell
sessions, but from its own `.t` files with indented `  $ ` lines, not from the fenced blocks of
the pages. Sybil parses the Markdown (its fenced-block lexer), keeps a namespace per document and
lets a parser name its evaluator, so only the evaluators below are ours.

The shell of a page runs in a sandbox that looks like the checkout to the commands, so they
run exactly as written: `unshare` gives it its own user, mount, network and PID namespaces;
the checkout is mounted at its own path as an overlay whose writes go to a tmpfs of the
sandbox (nothing in the source tree or the shared build/ changes), /tmp is a private directory
(the test's tmp_path), the network is a private loopback (the emulator's default ports
15020.. are free, whatever else runs on the machine), and every process the page started dies
with the sandbox. A checkout that itself lives under /tmp stays visible at its path. It needs
unprivileged user namespaces (Linux >= 5.11 for the overlay): where the machine restricts
them, a page's test is skipped with the reason (namespaces_missing), never failed.
"""
from __future__ import annotations

import os
import re
import secrets
import select
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sybil import Sybil
from sybil.parsers.markdown.lexers import FencedCodeBlockLexer

REPO = Path(__file__).resolve().parents[2]
NOT_RUN = re.compile(r"^#\s*not run by the tests:\s*(\S.*)$")
COMMAND_TIMEOUT = 300          # s: one command (make run may build first)
LANGS = ("sh", "console", "python")

# (pattern, replacement) on both sides of a comparison: what varies from run to run
NORMALISE = [
    (re.compile(r"127\.0\.0\.1:\d+"), "127.0.0.1:PORT"),
    (re.compile(r"\b(trm|mdp|port)=\d+(?![.\d])"), r"\1=PORT"),
    (re.compile(r"\b(t|seconds)=\d+(\.\d+)?s?"), r"\1=TIME"),
    (re.compile(r"\b\d+(\.\d+)? ?(s|ms)\b"), "TIME"),
    (re.compile(r"\b\d+(\.\d+)? wall s\b"), "TIME wall s"),
]


class DocCommandError(AssertionError):
    pass


def not_run_reason(source: str):
    first = source.lstrip("\n").split("\n", 1)[0].strip()
    m = NOT_RUN.match(first)
    return m.group(1) if m else None


def logical_lines(text: str):
    """The commands of a block: lines, a trailing backslash joining the next one."""
    out, cur = [], ""
    for line in text.split("\n"):
        if cur:
            cur += "\n" + line
        else:
            cur = line
        if cur.endswith("\\"):
            continue
        out.append(cur)
        cur = ""
    if cur:
        out.append(cur)
    return out


def normalise(text: str) -> str:
    for pat, rep in NORMALISE:
        text = pat.sub(rep, text)
    return "\n".join(re.sub(r"[ \t]+", " ", line).rstrip()
                     for line in text.strip("\n").split("\n"))


def line_pattern(line: str) -> re.Pattern:
    return re.compile(".*?".join(re.escape(p) for p in line.split("...")))


def matches(expected: str, actual: str) -> bool:
    """Line by line; a line `...` matches any number of lines, `...` in a line any text."""
    exp = normalise(expected).split("\n")
    act = normalise(actual).split("\n")
    pats = [None if e.strip() == "..." else line_pattern(e) for e in exp]
    reach = {0}                          # positions in act reachable after k expected lines
    for pat in pats:
        if pat is None:
            reach = set(range(min(reach), len(act) + 1)) if reach else set()
        else:
            reach = {j + 1 for j in reach if j < len(act) and pat.fullmatch(act[j])}
        if not reach:
            return False
    return len(act) in reach


class Sandbox:
    """One bash in its own namespaces, the checkout overlaid at its own path (see above)."""

    def __init__(self, tmp: Path, repo: Path = REPO):
        self.tmp = Path(tmp)
        for d in ("overlay", "tmp"):
            (self.tmp / d).mkdir(parents=True, exist_ok=True)
        self.mark = "__DOCRUN_" + secrets.token_hex(8)
        ovl = self.tmp / "overlay"           # a tmpfs: an overlay's upper layer needs a local fs
        loopback_up = ("import fcntl, socket, struct; fcntl.ioctl(socket.socket(), 0x8914, "
                       "struct.pack('16sH22x', b'lo', 0x1 | 0x8 | 0x40))")   # SIOCSIFFLAGS
        setup = "; ".join([
            "set -e",
            f"{shlex.quote(sys.executable)} -c {shlex.quote(loopback_up)}",
            f"mount -t tmpfs docs-sandbox {ovl}",
            f"mkdir {ovl}/upper {ovl}/work",
            f"mount -t overlay overlay -o lowerdir={repo},upperdir={ovl}/upper,"
            f"workdir={ovl}/work,userxattr {repo}",
            *self._keep_visible(repo, self.tmp / "tmp"),
            f"mount --rbind {self.tmp / 'tmp'} /tmp",
            f"cd {repo}",
            "set +e",
            "exec bash --norc --noprofile",
        ])
        env = dict(os.environ, LC_ALL="C.UTF-8", TERM="dumb", PYTHONDONTWRITEBYTECODE="1",
                   PYTHONUNBUFFERED="1")
        env.pop("MAKEFLAGS", None)
        env.pop("MIP_DOCS_WORKDIR", None)   # tests/docs/conftest.py's: the pages run as users do
        env.pop("MFLAGS", None)
        self.proc = subprocess.Popen(
            ["unshare", "-rmnp", "--fork", "--mount-proc", "--kill-child", "bash", "-c", setup],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, cwd="/",
            env=env)
        self.buf = b""
        try:
            out, status = self.run("true", timeout=30)
        except DocCommandError as e:
            out, status = str(e).strip().splitlines()[-1], None
        if status != 0:
            self.close()
            missing = namespaces_missing(self.tmp / "probe")
            if missing:          # the machine's limit, not the page's fault: said, not failed
                pytest.skip(f"the docs' pages cannot run here: {missing}")
            raise DocCommandError(f"the docs' sandbox did not start: {out.strip()}")

    @staticmethod
    def _keep_visible(repo: Path, private_tmp: Path):
        """A checkout under /tmp (a clone in /tmp, some CI runners) would vanish behind the
        private /tmp: its overlay is bound at the same path inside the private directory first,
        and the recursive bind of that directory over /tmp carries it along."""
        if not repo.is_relative_to("/tmp"):
            return []
        inside = private_tmp / repo.relative_to("/tmp")
        return [f"mkdir -p {shlex.quote(str(inside))}",
                f"mount --bind {shlex.quote(str(repo))} {shlex.quote(str(inside))}"]

    def run(self, command: str, timeout: float = COMMAND_TIMEOUT):
        """(output, exit status) of one command line in the page's shell."""
        script = (f"{{\n{command}\n}} </dev/null 2>&1\n"
                  f"printf '\\n%s %d\\n' {self.mark} $?\n")
        try:
            self.proc.stdin.write(script.encode())
            self.proc.stdin.flush()
        except BrokenPipeError:
            raise DocCommandError(f"the shell has ended before: {command}") from None
        deadline = time.monotonic() + timeout
        pat = re.compile(rb"\n" + self.mark.encode() + rb" (\d+)\n")
        fd = self.proc.stdout.fileno()
        while True:
            m = pat.search(self.buf)
            if m:
                out = self.buf[:m.start()]
                self.buf = self.buf[m.end():]
                return out.decode(errors="replace"), int(m.group(1))
            left = deadline - time.monotonic()
            if left <= 0:
                self.close()
                raise DocCommandError(f"no end after {timeout:.0f} s: {command}\n"
                                      f"{self.buf.decode(errors='replace')[-3000:]}")
            r, _, _ = select.select([fd], [], [], min(left, 1.0))
            if r:
                chunk = os.read(fd, 65536)
                if not chunk:
                    raise DocCommandError(f"the shell ended during: {command}\n"
                                          f"{self.buf.decode(errors='replace')[-3000:]}")
                self.buf += chunk

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()          # --kill-child: the PID namespace and all in it go too
        self.proc.wait(timeout=30)
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass


def namespaces_missing(tmp: Path):
    """Why this machine cannot give the sandbox what it needs (an unprivileged user and mount
    namespace with an overlay mount in it, Linux >= 5.11), or None. Ubuntu 24.04's AppArmor
    default and many containers restrict unprivileged user namespaces. The probe mounts nothing
    of the checkout: a sandbox that fails where this succeeds is a fault of the sandbox."""
    d = Path(tmp)
    d.mkdir(parents=True, exist_ok=True)
    probe = (f"mount -t tmpfs probe {d} && mkdir {d}/l {d}/u {d}/w && mount -t overlay overlay "
             f"-o lowerdir={d}/l,upperdir={d}/u,workdir={d}/w,userxattr {d}/l")
    try:
        r = subprocess.run(["unshare", "-rmnp", "--fork", "--mount-proc", "sh", "-c", probe],
                           capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"unshare could not run ({e})"
    if r.returncode == 0:
        return None
    said = (r.stderr.strip() or r.stdout.strip() or f"exit status {r.returncode}").splitlines()
    return ("unprivileged user namespaces with overlay mounts are not available "
            f"(unshare -rmnp: {said[-1]})")


def _session(example):
    ns = example.namespace
    if "_sandbox" not in ns:
        ns["_sandbox"] = Sandbox(ns["_tmp_path"] / "sandbox")
    return ns["_sandbox"]


def where(example):
    path = Path(example.path)
    return f"{path.relative_to(REPO) if path.is_relative_to(REPO) else path}:{example.line}"


def eval_sh(example):
    source = example.parsed
    if not_run_reason(source):
        return None
    sb = _session(example)
    for cmd in logical_lines(source):
        if not cmd.strip() or cmd.strip().startswith("#"):
            continue
        out, status = sb.run(cmd)
        if status != 0:
            raise DocCommandError(f"{where(example)}: exit status {status}: {cmd}\n{out[-3000:]}")
    return None


def parse_console(source: str):
    """[(command, expected output)] of a console block."""
    items = []
    lines = source.rstrip("\n").split("\n")
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("$ "):
            cmd = line[2:]
            while cmd.endswith("\\") and i + 1 < len(lines):
                i += 1
                cmd += "\n" + lines[i]
            items.append([cmd, []])
        elif items:
            items[-1][1].append(line)
        elif line.strip() and not line.startswith("#"):
            raise DocCommandError(f"text before the first `$ ` command: {line}")
        i += 1
    return [(c, "\n".join(o)) for c, o in items]


def eval_console(example):
    source = example.parsed
    if not_run_reason(source):
        return None
    sb = _session(example)
    for cmd, expected in parse_console(source):
        out, status = sb.run(cmd)
        if status != 0:
            raise DocCommandError(f"{where(example)}: exit status {status}: {cmd}\n{out[-3000:]}")
        if expected.strip() and not matches(expected, out):
            raise DocCommandError(f"{where(example)}: the output of `{cmd}` differs from the page"
                                  f"\n--- page (normalised)\n{normalise(expected)}"
                                  f"\n--- run (normalised)\n{normalise(out)}")
        if not expected.strip() and out.strip():
            raise DocCommandError(f"{where(example)}: `{cmd}` printed what the page does not "
                                  f"show:\n{out[-3000:]}")
    return None


def eval_python(example):
    source = example.parsed
    if not_run_reason(source):
        return None
    ns = example.namespace
    before = set(ns)
    code = compile(source, f"{where(example)}", "exec")
    saved = os.environ.get("PLCRT_CACHE")
    os.environ["PLCRT_CACHE"] = "off"      # the harness's build cache is shared build output
    try:
        exec(code, ns)
        for name in [n for n in ns if n not in before and n.startswith("test_")]:
            fn = ns[name]
            if callable(fn):
                tmp = ns["_tmp_path"] / f"py-{example.line}-{name}"
                tmp.mkdir(parents=True, exist_ok=True)
                fn(tmp) if fn.__code__.co_argcount else fn()
    finally:
        if saved is None:
            os.environ.pop("PLCRT_CACHE", None)
        else:
            os.environ["PLCRT_CACHE"] = saved
    return None


class BlockParser:
    """Sybil parser: fenced blocks of one language (the info string's first word)."""

    def __init__(self, language, evaluator):
        self.language = language
        self.lexer = FencedCodeBlockLexer(language=r"[^\n]*",
                                          mapping={"language": "language", "source": "source"})
        self.evaluator = evaluator

    def __call__(self, document):
        for region in self.lexer(document):
            words = region.lexemes["language"].split()
            if words and words[0] == self.language:
                region.parsed = str(region.lexemes["source"])
                region.evaluator = self.evaluator
                yield region


SYBIL = Sybil(parsers=[BlockParser("sh", eval_sh), BlockParser("console", eval_console),
                       BlockParser("python", eval_python)])


def run_page(path: Path, tmp_path: Path):
    """Runs every sh / console / python block of one page in order, in one sandbox; returns
    how many ran (the marked ones do not)."""
    doc = SYBIL.parse(Path(path))
    doc.namespace["_tmp_path"] = Path(tmp_path)
    ran = 0
    try:
        for example in doc.examples():
            example.evaluate()
            ran += not_run_reason(example.parsed) is None
    finally:
        sb = doc.namespace.get("_sandbox")
        if sb is not None:
            sb.close()
    return ran


def blocks(path: Path):
    """[(line, info string, source)] of every fenced block of a page (Sybil's lexer)."""
    doc = SYBIL.parse(Path(path))
    lexer = FencedCodeBlockLexer(language=r"[^\n]*",
                                 mapping={"language": "language", "source": "source"})
    out = []
    for region in lexer(doc):
        line = doc.text.count("\n", 0, region.start) + 1
        out.append((line, region.lexemes["language"].strip(), str(region.lexemes["source"])))
    return out


if __name__ == "__main__":          # by hand: python tests/docs/docrun.py PAGE.md
    import tempfile
    for page in sys.argv[1:]:
        with tempfile.TemporaryDirectory() as t:
            print(f"{page}: {run_page(Path(page).resolve(), Path(t))} blocks ran")
