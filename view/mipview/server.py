"""mip-view: the live view's web server (aiohttp) and its command line.

    mip-view [--preset NAME | --follow TRACE | --demo "ARGS"] [--station N]
             [--host 127.0.0.1] [--port 8610] [--paused] [--speed S] [--open]

The page (static/) gets the state as Server-Sent Events (/api/events, one event per change)
and sends its controls as POST /api/control {"action": ..., ...}. A live run (the default) is
stepped here, in the server's event loop, at the chosen speed (virtual seconds per real second);
--follow reads a trace file as it grows, --demo starts the real-time demo and follows its trace
(both read-only). Errors in options are one line, exit 2.
"""
from __future__ import annotations

import argparse
import asyncio
import errno
import json
import secrets
import shlex
import signal
import socket
import subprocess
import sys
import webbrowser
from pathlib import Path

STATIC = Path(__file__).with_name("static")
FRAME_S = 0.1                 # the page is updated at most every FRAME_S of real time
DEFAULT_PORT = 8610           # our choice: unassigned at IANA, far from the emulator's 15020+


class App:
    """One session (live or follow) and the clients watching it."""

    def __init__(self, session, workdir=None):
        self.session = session
        self.workdir = workdir
        self.version = 0
        self.changed = asyncio.Event()
        self._carry = 0.0          # fractional scan ticks owed at slow speeds
        self._cached = None
        self.error = None          # why the run stopped by itself (one line)
        self.closing = False       # the server stops: the event streams end
        self.boot = secrets.token_hex(4)   # this server's run: a page that reconnects to a
                                           # restarted server starts its versions over

    def touch(self):
        self.version += 1
        self._cached = None
        self.changed.set()
        self.changed = asyncio.Event()

    def state(self):
        if self._cached is None:
            st = self.session.state()
            st["version"] = self.version
            st["boot"] = self.boot
            st["error"] = self.error
            if st["mode"] == "live":
                from .session import PRESETS, SPEEDS
                from .chainview import CHAIN_TITLES
                st["presets"] = {k: {"title": p.title, "exercise": p.exercise,
                                     "mipsim": p.mipsim_args()} for k, p in PRESETS.items()}
                for k, title in CHAIN_TITLES.items():
                    st["presets"][k] = {"title": title, "exercise": "", "mipsim": ""}
                st["speeds"] = list(SPEEDS)
            self._cached = json.dumps(st)
        return self._cached

    async def run(self):
        """The clock: steps a live run, polls a followed trace."""
        from .session import ChainError, ViewError
        from mipcosim.sim import CosimError
        while True:
            await asyncio.sleep(FRAME_S)
            s = self.session
            if s.mode == "follow":
                try:
                    if not s.paused and s.poll():     # paused: the file is read on resume
                        self.touch()
                except Exception as e:    # a bug: one line here and on the page; the
                    self.error = f"internal error: {type(e).__name__}: {e}"   # clock goes on
                    print(f"mip-view: {self.error}", file=sys.stderr, flush=True)
                    self.touch()
                continue
            if s.paused:
                continue
            self._carry += s.speed * FRAME_S * 1e9 / s.tick
            n = int(self._carry)
            self._carry -= n
            try:
                for _ in range(n):
                    s.step()
            except (ChainError, ViewError, CosimError) as e:
                s.paused = True            # the run cannot go on: say why, keep the page
                self.error = str(e)
            except Exception as e:         # a bug: one line here and on the page, no traceback
                s.paused = True
                self.error = f"internal error: {type(e).__name__}: {e}"
                print(f"mip-view: {self.error}", file=sys.stderr, flush=True)
            if n:
                self.touch()

    def control(self, req: dict):
        """One control; returns nothing, raises ViewError with a line for the page."""
        from .session import ChainError, ViewError, make_live
        s = self.session
        action = req.get("action")
        if s.mode == "follow" and action not in ("pause", "resume"):
            raise ViewError(f"{action}: the view follows a trace (read-only)")
        try:
            if action == "pause":
                s.paused = True
            elif action == "resume":
                s.paused = False
            elif action == "step_scan":
                s.paused = True
                s.step()
            elif action == "step_slot":
                s.paused = True
                s.step_slot()
            elif action == "advance":
                s.paused = True
                s.advance(int(req.get("ms")))
            elif action == "speed":
                s.set_speed(float(req.get("value")))
            elif action == "loss":
                s.set_loss(req.get("direction"), float(req.get("value")))
            elif action == "lose":
                s.lose(req.get("what"))
            elif action == "restart":
                s.restart(req.get("plc"), req.get("kind", "cold"),
                          int(req.get("outage_ms", 1000)))
            elif action == "preset":
                new = make_live(req.get("name", ""), self.workdir)
                new.paused, new.speed = s.paused, s.speed
                s.close()
                self.session = new
                self.error = None
            else:
                raise ViewError(f"unknown action {action!r}")
        except (TypeError, ValueError) as e:
            raise ViewError(f"{action}: bad value ({e})") from None
        except ChainError as e:
            raise ViewError(f"{action}: {e}") from None
        self.touch()


def make_app(app: App):
    from aiohttp import web
    from .session import ViewError

    async def index(request):
        return web.FileResponse(STATIC / "index.html")

    async def state(request):
        return web.Response(text=app.state(), content_type="application/json")

    async def events(request):
        resp = web.StreamResponse(headers={"Content-Type": "text/event-stream",
                                           "Cache-Control": "no-cache"})
        await resp.prepare(request)
        try:
            while not app.closing:
                waiter = app.changed
                await resp.write(f"data: {app.state()}\n\n".encode())
                await waiter.wait()
                await asyncio.sleep(0.02)     # a burst of controls: one event
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        return resp

    async def control(request):
        # JSON only: another site's page in the same browser cannot send it without a CORS
        # preflight, which this server never grants
        if request.content_type != "application/json":
            return web.json_response({"error": "Content-Type must be application/json"},
                                     status=415)
        try:
            req = await request.json()
            if not isinstance(req, dict):
                raise ValueError
        except ValueError:
            return web.json_response({"error": "the body must be a JSON object"}, status=400)
        try:
            app.control(req)
        except ViewError as e:
            return web.json_response({"error": str(e)}, status=400)
        except Exception as e:             # a bug: one line here and on the page, no traceback
            msg = f"internal error: {type(e).__name__}: {e}"
            print(f"mip-view: {req.get('action')}: {msg}", file=sys.stderr, flush=True)
            return web.json_response({"error": msg}, status=500)
        return web.Response(text=app.state(), content_type="application/json")

    async def chunk(request):
        """One chunk of the diagram's history (rows.History), by number; its key in the
        X-Chunk-Key header (the page keeps it until the state names another)."""
        app.state()                        # the history of the latest state
        h = app.session.history
        try:
            i = int(request.query.get("i", ""))
            if not 0 <= i < len(h.chunks):
                raise ValueError
        except ValueError:
            return web.json_response({"error": f"no chunk {request.query.get('i')!r}"},
                                     status=404)
        return web.Response(text=h.svg(i), content_type="image/svg+xml",
                            headers={"X-Chunk-Key": h.chunks[i]["key"]})

    async def trace(request):
        s = app.session
        lines = s.trace() if s.mode == "live" else [json.dumps(d) for d in s.events]
        return web.Response(text="\n".join(lines) + "\n", content_type="application/x-ndjson")

    w = web.Application()
    w.router.add_get("/", index)
    w.router.add_get("/api/state", state)
    w.router.add_get("/api/events", events)
    w.router.add_get("/api/trace", trace)
    w.router.add_get("/api/chunk", chunk)
    w.router.add_post("/api/control", control)
    w.router.add_static("/static/", STATIC)
    return w


def parse(argv):
    from .session import CHAINS, PRESETS, SPEEDS
    ap = argparse.ArgumentParser(prog="mip-view", description=(
        "A live view in the browser: the MIP blocks in two soft PLCs over the emulated radio "
        "(co-simulation, driven from the page), or a trace file followed as it grows."))
    ap.add_argument("--preset", default="demo", choices=[*PRESETS, *CHAINS],
                    help="the run to start with (the exercises of docs/exercises.md; chain, "
                         "chain-push: the whole chain, relay to SCADA or to WinCC OA)")
    ap.add_argument("--follow", metavar="TRACE",
                    help="read-only: follow this JSON-lines trace (mip-emulator --trace, the "
                         "demo's build/plc/run/emulator-trace.jsonl, mipsim --trace)")
    ap.add_argument("--demo", metavar="ARGS", nargs="?", const="",
                    help="read-only: start the real-time demo (plc/demo.py, `make run`) with "
                         "these options (e.g. \"--realistic --records 20\") and follow its trace")
    ap.add_argument("--station", type=int, default=1,
                    help="with --follow: the station whose telegrams are drawn (default 1)")
    ap.add_argument("--host", default="127.0.0.1",
                    help="address to listen on (default 127.0.0.1: this PC only)")
    ap.add_argument("--port", type=int, default=DEFAULT_PORT, help="TCP port (0: any free one)")
    ap.add_argument("--speed", type=float, default=1.0,
                    help=f"virtual seconds per real second: {', '.join(f'{s:g}' for s in SPEEDS)}")
    ap.add_argument("--paused", action="store_true", help="start paused")
    ap.add_argument("--open", action="store_true", help="open the page in the default browser")
    ap.add_argument("--workdir", help="where the PLCs are built (default build/docs/plc)")
    a = ap.parse_args(argv)
    if a.demo is not None and a.follow:
        ap.error("--demo and --follow: one of them (--demo follows the demo's own trace)")
    if a.demo is not None:
        try:
            a.demo_args = shlex.split(a.demo)
        except ValueError as e:
            ap.error(f"--demo: {e}")
        if "--rundir" in a.demo_args:
            ap.error("--demo: mip-view chooses the demo's --rundir (build/view/demo)")
    if not 0 <= a.port <= 65535:
        ap.error("--port must be 0..65535")
    if a.speed not in SPEEDS:
        ap.error(f"--speed must be one of {', '.join(f'{s:g}' for s in SPEEDS)}")
    return a


def main(argv=None):
    a = parse(argv)
    from .session import REPO, Follow, ViewError, make_live
    demo = None
    try:
        if a.demo is not None:
            rundir = REPO / "build" / "view" / "demo"
            rundir.mkdir(parents=True, exist_ok=True)
            trace = rundir / "emulator-trace.jsonl"
            trace.unlink(missing_ok=True)          # the page shows this run, not the last one
            (rundir.parent / "demo.log").unlink(missing_ok=True)   # nor the last one's result
            # the log beside the run directory: the demo empties that at its start
            session = Follow(trace, a.station, wait=True, log=rundir.parent / "demo.log",
                             on_bad=log_bad)
        elif a.follow:
            session = Follow(a.follow, a.station, on_bad=log_bad)
        else:
            session = make_live(a.preset, a.workdir)
    except ViewError as e:
        print(f"mip-view: error: {e}", file=sys.stderr)
        return 2
    if session.mode == "live":
        session.speed = a.speed
    session.paused = a.paused
    try:
        sock = socket.create_server((a.host, a.port))
    except OSError as e:
        why = "in use" if e.errno == errno.EADDRINUSE else e.strerror
        print(f"mip-view: error: cannot listen on {a.host}:{a.port}: {why}"
              + (" (another mip-view? use --port)" if e.errno == errno.EADDRINUSE else ""),
              file=sys.stderr)
        session.close()
        return 2
    port = sock.getsockname()[1]
    url = f"http://{a.host if ':' not in a.host else '[' + a.host + ']'}:{port}/"
    if a.demo is not None:
        # the demo in a process of its own; its output (progress, result) goes to demo.log
        with open(rundir.parent / "demo.log", "w") as log:
            demo = subprocess.Popen([sys.executable, str(REPO / "plc" / "demo.py"), "--rundir",
                                     str(rundir), *a.demo_args], stdout=log,
                                    stderr=subprocess.STDOUT, cwd=REPO)
        print(f"mip-view: the demo runs in {rel(rundir)} (pid {demo.pid}, its output in "
              f"{rel(rundir.parent / 'demo.log')})", flush=True)
    try:
        asyncio.run(serve(App(session, a.workdir), sock, url, a.open))
    except KeyboardInterrupt:
        pass
    finally:
        if demo is not None and demo.poll() is None:
            demo.terminate()                    # the demo stops its emulator and PLCs
            try:
                demo.wait(20)
            except subprocess.TimeoutExpired:
                demo.kill()
                demo.wait()
    return 0


def log_bad(why):
    """A line of a followed trace that was skipped: one line in the log (the page shows it)."""
    print(f"mip-view: {why}", file=sys.stderr, flush=True)


def rel(path):
    """A path as the user gave it, or relative to the current directory when it is in it."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


async def serve(app, sock, url, open_browser):
    from aiohttp import web
    runner = web.AppRunner(make_app(app), access_log=None, shutdown_timeout=1.0)
    await runner.setup()
    site = web.SockSite(runner, sock)
    await site.start()
    what = "following " + rel(app.session.path) if app.session.mode == "follow" else \
        f"live run, preset {app.session.preset_name}"
    print(f"mip-view: {what}: open {url} (Ctrl-C to stop)", flush=True)
    if open_browser:
        webbrowser.open(url)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    clock = asyncio.create_task(app.run())
    await stop.wait()
    clock.cancel()
    app.closing = True
    app.touch()                    # wakes the event streams, which then end
    await runner.cleanup()
    app.session.close()


if __name__ == "__main__":
    sys.exit(main())
