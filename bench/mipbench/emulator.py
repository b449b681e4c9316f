"""Figure 3: the emulator's Modbus TCP throughput against pymodbus and a bare libmodbus server."""
from __future__ import annotations

import re
import statistics
import subprocess
from pathlib import Path

from mipprobe.regmap import TRM810
from plcharness.procs import free_port

from .common import BUILD, BenchError, EMU, PY, Server, error, line, run

# ---------------------------------------------------------------- 3. emulator throughput

def client_rate(port, unit, addr, count):
    out = run([BUILD / "mb_client", "127.0.0.1", port, unit, addr, 125, count], timeout=900)
    return float(re.search(r"rate=([\d.]+)", out).group(1))


def cpu_ns(pid):
    """Time the (single-threaded) process has run on a CPU, ns (/proc/PID/schedstat)."""
    try:
        return int(Path(f"/proc/{pid}/schedstat").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def served(srv, port, unit, addr, count):
    """(requests/s seen by the client, server CPU µs per request or None)."""
    c0 = cpu_ns(srv.p.pid)
    rate = client_rate(port, unit, addr, count)
    c1 = cpu_ns(srv.p.pid)
    cpu = (c1 - c0) / 1000 / (count * 1.1) if c0 is not None and c1 is not None else None
    return rate, cpu    # the client's warm-up is 10 % more requests (bench/mb_client.c)


def fig_emulator_throughput(quick):
    count = 1000 if quick else 10000
    rounds = 1 if quick else 5            # interleaved, so the three see the same machine load
    name_p, name_b = "emu_throughput_vs_pymodbus", "emu_throughput_vs_bare"
    rates = {"emu": [], "pymodbus": [], "bare": []}
    cpus = {"emu": [], "pymodbus": [], "bare": []}

    def note(key, rc):
        rates[key].append(rc[0])
        if rc[1] is not None:
            cpus[key].append(rc[1])

    try:
        for _ in range(rounds):
            with Server([EMU, "--mdp-port", 0, "--trm-base-port", 0, "--stations", 1]) as s:
                trm = int(re.search(r"trm=(\d+)", s.first).group(1))
                note("emu", served(s, trm, 1, TRM810.read_status, count))
            port = free_port()
            with Server([PY, "-m", "mipbench.pymodbus_server", port]) as s:
                note("pymodbus", served(s, port, 1, 0, count))
            with Server([BUILD / "mb_bare_server", 0]) as s:
                port = int(re.search(r"port=(\d+)", s.first).group(1))
                note("bare", served(s, port, 1, 0, count))
    except (BenchError, subprocess.SubprocessError, OSError, AttributeError) as e:
        error(name_p, str(e))
        error(name_b, str(e))
        return
    e, py, bare = (statistics.median(rates[k]) for k in ("emu", "pymodbus", "bare"))
    if all(cpus.values()):
        ce, cp, cb = (statistics.median(cpus[k]) for k in ("emu", "pymodbus", "bare"))
        cpu_p = f"; server CPU per request {ce:.1f} vs {cp:.1f} µs"
        cpu_b = f"; server CPU per request {ce:.1f} vs {cb:.1f} µs"
    else:
        cpu_p = cpu_b = ""
    common = (f"FC3 125 registers, libmodbus client (bench/mb_client.c), {count} requests, "
              f"median of {rounds}")
    line(name_p, f"{e / py:.2f} x pymodbus (emulator {e:.0f}/s, pymodbus server {py:.0f}/s"
         f"{cpu_p}; {common}; target >= 5)", "OK" if e / py >= 5 else "MISSED")
    line(name_b, f"{e / bare:.2f} x bare libmodbus (emulator {e:.0f}/s, modbus_reply server "
         f"{bare:.0f}/s{cpu_b}; {common}; target >= 0.5)", "OK" if e / bare >= 0.5 else "MISSED")
