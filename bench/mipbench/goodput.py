"""Figure 1: goodput of the stop-and-wait and the pipelined transfer against their loss models
(co-simulation)."""
from __future__ import annotations


from .common import BenchError, MS, PAYLOAD, SEC, cosim_available, cosim_missing, error, failure, line

# ---------------------------------------------------------------- 1. goodput

def goodput_model(p, payload=PAYLOAD):
    """Payload registers per poll of the station at independent loss p in each direction
    (docs/benchmarks.md): a record needs a poll and its answer through (1-p)^2 per poll, then
    its acknowledgement needs one poll through (1-p); E[polls per record] = 1/(1-p)^2 + 1/(1-p)."""
    return payload / (1 / (1 - p) ** 2 + 1 / (1 - p))




def goodput_cosim(p, records, seed, workdir):
    """Polls and payload registers of the window from the 5th record (past the start-up: the
    sender's quiet wait before record 1) to the sender's last acknowledgement."""
    import mipcosim.programs as L
    import mipcosim.sim as S
    s = S.Setup(stations=1, records=records, payload=PAYLOAD, loss=p, seed=seed,
                radio=S.Radio.realistic())
    warm = 5
    with S.LoggerLink(s, workdir) as ch:
        step = 50 * MS
        limit = records * 60 * SEC
        got = lambda: ch.mw(("cen", 0), L.peer_base(1) + L.R_REC_LO)  # noqa: E731
        polls0 = rec0 = None
        while not ch.finished():
            if ch.now > limit:
                raise BenchError(f"transfer of {records} records at {p:.0%} loss not finished "
                                 f"after {ch.now / SEC:.0f} virtual s")
            ch.run_for(step)
            if polls0 is None and got() >= warm:
                polls0, rec0 = ch.radio_stats()["polls"], got()
        polls1 = ch.radio_stats()["polls"]
    if polls0 is None or polls1 <= polls0:
        raise BenchError(f"no measurement window ({records} records)")
    return polls1 - polls0, (records - rec0) * PAYLOAD


def fig_goodput(quick, workdir):
    ok, why = cosim_available()
    records = {0.0: 150, 0.1: 200, 0.3: 200} if quick else {0.0: 1000, 0.1: 1500, 0.3: 1500}
    seeds = [1] if quick else [1, 2, 3]
    for p in (0.0, 0.1, 0.3):
        name = f"goodput_{int(p * 100)}pct"
        polls = payload = 0
        how = ""
        if ok:
            try:
                for seed in seeds:
                    a, b = goodput_cosim(p, records[p], seed, workdir)
                    polls += a
                    payload += b
                how = ("cosim: plc/outstation.st + plc/central.st (st_lib via stc) in the soft-PLC "
                       "over the emulator core, 9600 bit/s, 10 ms scans")
            except Exception as e:  # noqa: BLE001 - report, go on with the other figures
                why = f"cosim failed: {failure(e)}"
        if not how:
            # one model of the chain: no figure without the kernel (no scripted copy of it)
            error(name, why)
            continue
        g = payload / polls
        n = payload // PAYLOAD
        if p == 0:
            bound = PAYLOAD / 2
            r = g / bound
            line(name, f"{r:.3f} of bound ({g:.2f} of {bound:.1f} payload registers per poll, "
                 f"{n} records in {polls} polls, {len(seeds)} seed(s); {how}; target >= 0.95)",
                 "OK" if r >= 0.95 else "MISSED")
        else:
            m = goodput_model(p)
            r = g / m
            line(name, f"{r:.3f} of model ({g:.2f} vs {m:.2f} payload registers per poll, "
                 f"{n} records in {polls} polls, {len(seeds)} seed(s); {how}; target 0.90..1.10)",
                 "OK" if 0.9 <= r <= 1.1 else "MISSED")


def pipelined_model(p, records, payload=PAYLOAD):
    """Payload registers per poll of the station with MIP_Sender's window 2 (st_lib/PROTOCOL.md
    P27, docs/benchmarks.md) at independent loss p: a pipelined record needs a poll and its
    answer through, (1-p)^2 per poll. Then the link confirms it (the slot's third telegram):
    if that is lost (p) the sender cannot write the next record until the acknowledgement
    comes down with a later poll, 1/(1-p) polls, whose answer is the modem's repetition of the
    record; E = 1/(1-p)^2 + p/(1-p). Records 1 and 2 and the last one of a transfer go stop and
    wait (E of goodput_model); one transfer of `records`."""
    return records * payload / ((records - 2) * pipelined_polls(p) + 2 * stop_and_wait_polls(p))


def stop_and_wait_polls(p):
    return 1 / (1 - p) ** 2 + 1 / (1 - p)


def pipelined_polls(p):
    return 1 / (1 - p) ** 2 + p / (1 - p)


def goodput_pair(stations, p, records, workdir):
    """One transfer of `records` full records per station, stop and wait and window 2, the
    same seed and radio: (payload registers per poll, per virtual second) of each."""
    from mipcosim.sim import SEC, Network
    timeout_ms = max(3000, 2000 * stations)   # > 5 poll cycles: a lost acknowledgement is
    out = {}                                  # not a retransmission (which closes the window)
    for window in (1, 2):
        with Network(stations, workdir / f"pipe-{stations}", records=records, payload=PAYLOAD,
                     loss=p, seed=1, tick_ms=10, timeout_ms=timeout_ms, window=window) as net:
            limit = 60 + records * stations * 4 / (1 - p) ** 2
            # each station's polls and time up to its last acknowledgement (the MDP goes on
            # polling a station that has finished: those empty polls are not the transfer's)
            polls, ends, left = 0, [], set(range(1, stations + 1))
            while left:
                if net.now > limit * SEC:
                    raise BenchError(f"{stations} station(s), {p:.0%} loss, window {window}: "
                                     f"not finished after {limit:.0f} virtual s")
                net.run_for(20 * MS)
                for s in [s for s in left if net.read_out(s)]:
                    polls += net.radio_stats([s])["polls"]
                    ends.append(net.now / SEC)
                    left.discard(s)
            net.run_for(SEC)                 # late duplicates would show in the check
            problems = net.check()
            if problems:
                raise BenchError(f"window {window}: {problems[0]}")
            regs = stations * records * PAYLOAD
            out[window] = (regs / polls, regs / max(ends))
    return out


def fig_goodput_pipelined(quick, workdir):
    name = "goodput_pipelined"
    if cosim_missing(name, pending=True):
        return
    records = {1: 40, 4: 20, 16: 10} if quick else {1: 150, 4: 80, 16: 80}
    # the quick run (make check's bench test: the line's shape) leaves out the 16 stations,
    # two thirds of its time
    sizes = (1, 4) if quick else (1, 4, 16)
    cells, fit = [], []
    try:
        for n in sizes:
            for p in (0.0, 0.1, 0.3):
                g = goodput_pair(n, p, records[n], workdir)
                m = pipelined_model(p, records[n])
                cells.append((n, p, g[2][0] / g[1][0], g[2][1] / g[1][1]))
                fit.append(g[2][0] / m)
    except Exception as e:  # noqa: BLE001 - report, go on with the other figures
        error(name, failure(e))
        return
    per_poll = "; ".join(f"{n} station{'s' if n > 1 else ''} " + "/".join(
        f"{r:.2f}" for m, _, r, _ in cells if m == n) for n in sizes)
    per_s = "; ".join(f"{n}: " + "/".join(f"{r:.2f}" for m, _, _, r in cells if m == n)
                      for n in sizes)
    model = "/".join(f"{stop_and_wait_polls(p) / pipelined_polls(p):.2f}" for p in (0.0, 0.1, 0.3))
    worst0 = min(r for _, p, r, _ in cells if p == 0)
    inside = sum(1 for f in fit if 0.9 <= f <= 1.1)
    outside = ", ".join(f"{n} st. {p:.0%}: {f:.2f}" for (n, p, _, _), f in zip(cells, fit)
                        if not 0.9 <= f <= 1.1)
    met = worst0 >= 1.8 and inside == len(fit)
    line(name, f"{worst0:.2f} at 0 % loss (window 2 / stop and wait, payload per poll, at 0/10/30 % "
         f"loss: {per_poll}; steady-state model {model}; window 2 within 10 % of its model in "
         f"{inside} of {len(fit)} cells{' (outside: ' + outside + ')' if outside else ''}; per virtual second, "
         f"where the data telegrams' air time dominates: {per_s}; cosim: mipcosim.sim.Network, plc/outstation.st "
         f"+ plc/central_many.st, 9600 bit/s, 10 ms scans, tTimeout > 5 poll cycles; target >= "
         f"1.8 at 0 % loss, model within 10 %)", "OK" if met else "MISSED")
