"""Figure 5b: peak memory of the emulator, a soft-PLC and the co-simulation."""
from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

from mipprobe.regmap import MDP810, TRM810
from plcharness.config import Config

from .common import BUILD, BenchError, EMU, RSS_RUN, Server, error, line, read_rss, run_rss
from .scan_cost import build_pair
from .emulator import client_rate

def fig_memory(quick):
    try:
        floor = run_rss(["/bin/true"])
    except (BenchError, subprocess.SubprocessError, OSError) as e:
        floor = f"? ({e})"
    note = f"ru_maxrss via bench/rss_run.c, floor of /bin/true {floor} KiB; no target"
    # runtime executable: the bench pair program, virtual time, with a Modbus master of 1 or 64
    # devices (MDP unit ids 1..n of a running emulator, one cyclic FC3 range each)
    try:
        exe = BUILD / "pair-stc" / "plc"
        if not exe.is_file():
            exe = build_pair("stc")
        scans = 1000 if quick else 10000
        with Server([EMU, "--mdp-port", 0, "--trm-base-port", 0, "--stations", 64]) as emu:
            mdp = int(re.search(r"mdp=[\d.]+:(\d+)", emu.first).group(1))
            for n in (1, 64):
                name = f"peak_rss_runtime_{n}st"
                try:
                    conf = BUILD / f"rss_runtime_{n}.conf"
                    cfg = Config()
                    cfg.add("master", polling_period="100ms", timeout="1s")
                    for d in range(1, n + 1):
                        cfg.add("device", f"mdp{d}", host="127.0.0.1", port=mdp, unit_id=d)
                        cfg.add("read", f"r{d}", device=f"mdp{d}", start=MDP810.read_status, size=12,
                                image=f"%IW{100 + 12 * (d - 1)}", policy="cycle")
                    cfg.write(conf)
                    rss = run_rss([exe, "-c", conf, "-m", "virtual", "-n", scans])
                    line(name, f"{rss} KiB (plc executable of bench/st/bench_pair.st, {scans} "
                         f"virtual scans of 10 ms, Modbus master of {n} device{'s' * (n > 1)} "
                         f"(TCP to the emulator's MDP, 12 registers every 100 ms each); {note})",
                         "INFO")
                except (BenchError, subprocess.SubprocessError, OSError) as e:
                    error(name, str(e))
    except (BenchError, subprocess.SubprocessError, OSError, AttributeError) as e:
        for n in (1, 64):
            error(f"peak_rss_runtime_{n}st", str(e))
    for n in (1, 64):
        name = f"peak_rss_emulator_{n}st"
        try:
            with tempfile.NamedTemporaryFile(dir=BUILD, suffix=".rss") as f:
                srv = Server([RSS_RUN, f.name, EMU, "--mdp-port", 0, "--trm-base-port", 0,
                              "--stations", n])
                try:
                    mdp = int(re.search(r"mdp=[\d.]+:(\d+)", srv.first).group(1))
                    trms = [int(x) for x in re.search(r"trm=([\d,]+)", srv.first).group(1).split(",")]
                    reqs = 20 if quick else 200
                    for s in range(1, n + 1):        # touch every station's buffers
                        client_rate(mdp, s, MDP810.read_status, reqs)
                        client_rate(trms[s - 1], 1, TRM810.read_status, reqs)
                finally:
                    srv.stop()
                rss = read_rss(Path(f.name))
            line(name, f"{rss} KiB (mip-emulator, {n} station{'s' * (n > 1)}, {2 * n} ports, "
                 f"{reqs} FC3 reads per port; {note})", "INFO")
        except (BenchError, subprocess.SubprocessError, OSError, AttributeError) as e:
            error(name, str(e))
