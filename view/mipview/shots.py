"""Screenshots of the page, one per preset, taken in Debian's Chromium through Playwright: the
pictures of docs/view.md (docs/img/view-*.png, `make view-shots`) and of the browser tests
(build/view/). Each PNG carries a tEXt chunk "mip-view" that says what it shows (the preset and
the virtual time), so tests/view can check a committed picture came from here.

    python -m mipview.shots OUTDIR [--preset NAME ...]     (make view-shots: the docs' ones)
"""
from __future__ import annotations

import argparse
import json
import os
import re
import struct
import subprocess
import sys
import urllib.request
import zlib
from pathlib import Path

from plcharness.procs import stop
from stc import oneline

from .session import CHAINS, PRESETS

CHROMIUM = os.environ.get("MIP_VIEW_CHROMIUM", "/usr/bin/chromium")
# Chromium as root in a closed network (no sandbox, nothing fetched in the background)
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]
VIEWPORT = {"width": 1500, "height": 1000}
# the presets pictured in docs/view.md (docs/img/view-<preset>.png); the tests take them all
DOCS_PRESETS = ("demo", "ex2", "ex6-outstation", "chain")
AFTER_MS = 400             # the picture: this long after the moment that matters (our choice)
STEP_MS = 100


class Server:
    """mip-view in a process of its own (paused unless paused=False), on a free port."""

    def __init__(self, *args, workdir=None, paused=True):
        cmd = [sys.executable, "-m", "mipview.server", "--port", "0", *args]
        cmd += ["--paused"] if paused else []
        if workdir:
            cmd += ["--workdir", str(workdir)]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True)
        self.said = []
        m = None
        while m is None:
            line = self.proc.stdout.readline()
            self.said.append(line)
            m = re.search(r"open (\S+)", line)
            if not line:
                break
        if not m:
            err = self.proc.stderr.read()
            self.proc.wait()
            raise RuntimeError(f"mip-view did not start: {(''.join(self.said) + err).strip()}")
        self.url = m.group(1)

    def control(self, **req):
        r = urllib.request.Request(self.url + "api/control", data=json.dumps(req).encode(),
                                   headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(r, timeout=60) as f:
            return json.load(f)

    def get(self, path):
        with urllib.request.urlopen(self.url + path, timeout=60) as f:
            return f.read().decode()

    def close(self):
        stop(self.proc, timeout=10)


def launch(pw):
    """Debian's Chromium (Playwright makes a fresh profile directory for every launch)."""
    return pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)


def moment(server, limit_ms=60_000):
    """Advances the paused run to the picture's moment: AFTER_MS after the first lost telegram
    or restart (what the exercise is about), or after the end of the transfer; returns the
    state."""
    st = server.control(action="advance", ms=STEP_MS)
    while st["t_ms"] < limit_ms:
        if st["done"] or any(r["lost"] or "restart" in r["text"].lower() for r in st["rows"]):
            break
        st = server.control(action="advance", ms=STEP_MS)
    return server.control(action="advance", ms=AFTER_MS)


def describe(preset, t_ms):
    if preset in CHAINS:
        return f"mip-view preset {preset} at {t_ms} ms (the whole chain, {CHAINS[preset]})"
    return f"mip-view preset {preset} at {t_ms} ms (mipsim {PRESETS[preset].mipsim_args()})"


def with_text(png: bytes, key: str, text: str) -> bytes:
    """The PNG with a tEXt chunk key=text after its header chunk."""
    body = key.encode("latin-1") + b"\0" + text.encode("latin-1")
    chunk = struct.pack(">I", len(body)) + b"tEXt" + body + struct.pack(
        ">I", zlib.crc32(b"tEXt" + body))
    end_ihdr = 8 + 8 + 13 + 4
    return png[:end_ihdr] + chunk + png[end_ihdr:]


def png_text(path) -> dict:
    """The tEXt chunks of a PNG file."""
    data = Path(path).read_bytes()
    out, i = {}, 8
    while i + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[i:i + 8])
        if kind == b"tEXt":
            k, _, v = data[i + 8:i + 8 + n].partition(b"\0")
            out[k.decode("latin-1")] = v.decode("latin-1")
        i += 12 + n
    return out


def png_size(path):
    w, h = struct.unpack(">II", Path(path).read_bytes()[16:24])
    return w, h


def take(outdir, presets=None, workdir=None, browser=None):
    """One PNG per preset in outdir (view-<preset>.png); returns {preset: (path, state)}.
    browser: a Playwright browser to use (default: Chromium launched here)."""
    if browser is None:
        from playwright.sync_api import sync_playwright
        with sync_playwright() as pw:
            b = launch(pw)
            try:
                return take(outdir, presets, workdir, b)
            finally:
                b.close()
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    server = Server(workdir=workdir)
    out = {}
    try:
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(server.url)
        for name in presets or [*PRESETS, *CHAINS]:
            server.control(action="preset", name=name)
            st = moment(server)
            # the page has drawn this state (the event stream's copy of it)
            page.wait_for_function(f"document.body.dataset.version >= {st['version']}")
            page.evaluate("window.scrollTo(0, 0)")
            path = outdir / f"view-{name}.png"
            png = page.screenshot()
            path.write_bytes(with_text(png, "mip-view", describe(name, st["t_ms"])))
            out[name] = (path, st)
        page.close()
    finally:
        server.close()
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="mipview.shots",
                                 description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("outdir")
    ap.add_argument("--preset", action="append", choices=[*PRESETS, *CHAINS])
    a = ap.parse_args(argv)
    if not Path(CHROMIUM).is_file():
        print(f"mipview.shots: error: {CHROMIUM} missing (Debian package chromium)",
              file=sys.stderr)
        return 2
    def shoot():
        for name, (path, st) in take(a.outdir, a.preset).items():
            print(f"{path}: {describe(name, st['t_ms'])}")
    return oneline.run("mipview.shots", shoot, errors=(RuntimeError,))


if __name__ == "__main__":
    sys.exit(main())
