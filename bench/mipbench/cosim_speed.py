"""Figure 4: co-simulation speed (virtual against wall time) and its scaling with stations."""
from __future__ import annotations

import time
from pathlib import Path

from .common import BenchError, MS, PAYLOAD, SEC, cosim_missing, error, failure, line

# ---------------------------------------------------------------- 4. cosim speed

def cosim_speed_run(virt_s, workdir: Path, stations=8, transport="inproc", tick_ms=100):
    """`stations` outstation soft-PLCs (plc/outstation.st) and ceil(stations / 4) central
    soft-PLCs (plc/central.st holds 4 receivers, cosim/mipcosim/programs.py MAX_STATIONS = 4; the
    k-th central serves stations 4k+1..4k+4 with those unit ids) with `tick_ms` scans over one
    emulated network (one MDP-810) in libmipcosim's lockstep virtual time. transport "inproc":
    the kernel (request ADUs handed to the emulator core); "socketpair" / "tcp": libmodbus
    over socketpairs (what the co-simulation used before) / TCP on 127.0.0.1."""
    import resource

    import mipcosim.programs as L
    import mipcosim.sim as S
    from plcharness import Plc

    workdir.mkdir(parents=True, exist_ok=True)
    kernel = S.Kernel(stations, radio=S.Radio.realistic(), error=BenchError)
    plcs = []

    def add(build, conf, params, wires):
        plc = Plc(build, workdir, config=conf)
        plcs.append(plc)
        pid = kernel.add_plc(plc, tick_ms * MS)
        for dev, ep in wires:
            kernel.connect(pid, plc, dev, ep, transport)
        for i, w in enumerate(params.words()):
            plc[f"%MW{i}"] = w

    try:
        out_b = S.build("outstation", False, workdir, tick_ms=tick_ms)
        cen_b = S.build("central", False, workdir, tick_ms=tick_ms)
        oconf = workdir / "outstation.conf"
        oconf.write_text(L.outstation_config(15021))
        big = 60000
        for s in range(1, stations + 1):
            # the record data carry the station number the central's receiver expects
            add(out_b, oconf, L.Params(records=big, payload=PAYLOAD, station=(s - 1) % 4 + 1),
                [("trm", s)])
        for k in range((stations + 3) // 4):
            n = min(4, stations - 4 * k)
            conf = workdir / f"central{k}.conf"
            cfg = L.central_model(15020, n)
            for dev in cfg.devices:         # this group's stations
                dev.keys["unit_id"] = str(int(dev["unit_id"]) + 4 * k)
            cfg.write(conf)
            add(cen_b, conf, L.Params(records=big, payload=PAYLOAD, station=0),
                [(f"mdp{i}", 0) for i in range(1, n + 1)])
        ru0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        kernel.run_until(virt_s * SEC)
        wall = time.perf_counter() - t0
        ru1 = resource.getrusage(resource.RUSAGE_SELF)
        cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
        sys_cpu = ru1.ru_stime - ru0.ru_stime
        st = kernel.radio_stats()
        return dict(wall=wall, cpu=cpu, sys_cpu=sys_cpu, scans=st["scans"],
                    reqs=st["requests"], polls=st["polls"], blocks=st["blocks_up"],
                    rss_mb=ru1.ru_maxrss / 1024, centrals=(stations + 3) // 4)
    finally:
        for plc in plcs:
            plc.close()
        kernel.close()


def fig_cosim_speed(quick, workdir):
    name = "cosim_speed"
    if cosim_missing(name, pending=True):
        return
    virt = 60 if quick else 600
    try:
        r = cosim_speed_run(virt, workdir)
    except Exception as e:  # noqa: BLE001 - report, go on with the other figures
        error(name, failure(e))
        return
    if r["blocks"] == 0:
        error(name, f"no record went over the radio in {virt} virtual s: the chain is not running")
        return
    x = virt / r["wall"]
    cpu, sys_cpu = r["cpu"], r["sys_cpu"]
    rc = virt / cpu if cpu > 0 else float("inf")
    line(name, f"{x:.0f} x real time ({virt} virtual s in {r['wall']:.3f} wall s; per CPU second "
         f"{rc:.0f} x, {sys_cpu / cpu if cpu else 0:.0%} of it in the kernel; 8 outstation + 2 "
         f"central soft-PLCs, 100 ms scans, 9600 bit/s; {r['scans']} scans, {r['reqs']} Modbus "
         f"requests through the in-process transport, {r['polls']} polls, {r['blocks']} records "
         f"up; target >= 1000)",
         "OK" if x >= 1000 else "MISSED")


def fig_cosim_scale(quick, workdir):
    """The largest MIP network: 247 outstation soft-PLCs and ONE central program with 247
    receivers behind one shared Modbus client (plc/central_many.st with its image generated
    for 247 stations by mipprograms.image_many, plcrt `unit_id = %QWn`) on one MDP-810, in the kernel (mipcosim.sim.Network)."""
    import resource

    name = "cosim_scale"
    if cosim_missing(name, pending=True):
        return
    virt = 10 if quick else 60
    stations = 247
    try:
        from mipcosim.sim import SEC, Network
        with Network(stations, workdir, records=60000, payload=PAYLOAD, tick_ms=100) as net:
            t0 = time.perf_counter()
            net.run_for(virt * SEC)
            wall = time.perf_counter() - t0
            st = net.radio_stats()
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    except Exception as e:  # noqa: BLE001 - report, go on with the other figures
        error(name, failure(e))
        return
    if st["polls"] == 0:
        error(name, f"no poll in {virt} virtual s: the chain is not running")
        return
    x = virt / wall
    line(name, f"{x:.0f} x real time ({virt} virtual s in {wall:.2f} wall s; peak RSS "
         f"{rss:.0f} MB; {stations} outstation soft-PLCs + ONE central program of {stations} "
         f"receivers on one MDP-810, 100 ms scans, 9600 bit/s; {st['scans']} scans, "
         f"{st['requests']} Modbus requests, {st['polls']} polls, {st['blocks_up']} records up; "
         f"target >= 100 x)", "OK" if x >= 100 else "MISSED")
