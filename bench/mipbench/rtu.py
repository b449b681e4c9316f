"""Figure 1c: the serial link (issue 27): records per second over Modbus RTU and the FC23 gain."""
from __future__ import annotations

import statistics

from .common import BenchError, MS, PAYLOAD, SEC, cosim_missing, error, failure, line

# ---------------------------------------------------------------- 1c. the serial link (issue 27)

def records_per_s(baud, records, seed, workdir, status_first=False, window=1, fc23=False,
                  payload=PAYLOAD):
    """Records per virtual second from the 5th record (past the start-up) to the end of one
    transfer; the PLCs on Modbus TCP (baud 0) or RTU 8E1 at baud (the line's time counted in
    virtual time), realistic radio, 122-register records."""
    import mipcosim.programs as L
    import mipcosim.sim as S
    from mipcosim.cli import link_timeout_ms
    s = S.Setup(stations=1, records=records, payload=payload, seed=seed, radio=S.Radio.realistic(),
                link_baud=baud, timeout_ms=3000 + link_timeout_ms(baud), status_first=status_first,
                window=window, fc23=fc23)
    with S.LoggerLink(s, workdir) as ch:
        got = lambda: ch.mw(("cen", 0), L.peer_base(1) + L.R_REC_LO)  # noqa: E731
        t0 = r0 = None
        while not ch.finished():
            if ch.now > records * 60 * SEC:
                raise BenchError(f"{records} records at {baud or 'TCP'} not finished after "
                                 f"{ch.now / SEC:.0f} virtual s")
            ch.run_for(20 * MS)
            if t0 is None and got() >= 5:
                t0, r0 = ch.now, got()
        if t0 is None or ch.now <= t0:
            raise BenchError("no measurement window")
        return (records - r0) / ((ch.now - t0) / SEC)


def rtu_char_ms(baud):
    """One character of 8E1 (start, 8 data, parity, stop: 11 bits) in ms"""
    return 11_000 / baud


def rtu_gap_ms(baud):
    """The 3.5-character silence between RTU frames (1.75 ms above 19,200 baud)"""
    return 1.75 if baud > 19200 else 3.5 * rtu_char_ms(baud)


def rtu_cycle_bound_ms(baud, payload=PAYLOAD):
    """The shortest time a record can take in a stop-and-wait transfer (window 1) with both PLCs
    on RTU 8E1 at baud over the realistic radio, everything in series as it depends on what
    comes before it: the record's FC16 (after the answer of the read that brought the last
    acknowledgement), the station's answer to a poll (one slot gap, then its air time), the
    answer of the central's read of status, count and record, the acknowledgement's FC16 of
    one register, the poll carrying it, the answer of the outstation's read of status, count
    and acknowledgement (status_first 3). Every read reaches the modem just as its data arrive;
    no scan, no wait for a poll; docs/serial.md has the terms."""
    import mipcosim.sim as S
    radio = S.Radio.realistic()
    air = lambda regs: (radio.overhead_bytes + 2 * regs) * 8_000 / radio.bitrate  # noqa: E731
    c, gap, regs = rtu_char_ms(baud), rtu_gap_ms(baud), payload + 1
    return (gap + (9 + 2 * regs) * c                      # record: FC16 request
            + radio.slot_gap_ns / MS + air(regs)          # the station's answer
            + gap + (5 + 2 * (regs + 2)) * c              # central: the read's answer
            + gap + (9 + 2) * c                           # acknowledgement: FC16 request
            + air(1)                                      # the poll carrying it
            + gap + (5 + 2 * 3) * c)                      # outstation: the read's answer


def fig_goodput_rtu(quick, workdir):
    import mipcosim.programs as L
    name = "goodput_rtu"
    if cosim_missing(name, pending=False):
        return
    records = 30 if quick else 120
    seeds = [1] if quick else [1, 2]
    best = L.RTU_STATUS_FIRST
    try:
        res = {}
        for sf in (False, True, best):
            for baud in (0, 9600, 19200, 115200):
                if baud == 0 and sf:
                    continue
                res[(baud, sf)] = statistics.mean(
                    records_per_s(baud, records, seed, workdir, status_first=sf) for seed in seeds)
    except Exception as e:  # noqa: BLE001 - report, go on with the other figures
        error(name, failure(e))
        return
    tcp = res[(0, False)]
    ratio = {k: v / tcp for k, v in res.items() if k[0]}
    r = ratio[(19200, best)]
    cells = lambda sf: "/".join(f"{ratio[(b, sf)]:.2f}" for b in (9600, 19200, 115200))  # noqa: E731
    bound = rtu_cycle_bound_ms(19200)
    line(name, f"{r:.2f} of TCP at 19200 baud (records/s as a ratio to TCP {tcp:.2f}/s, at "
         f"9600/19200/115200 baud 8E1: status_first {best} {cells(best)}, status_first yes "
         f"{cells(True)}, whole read area each poll {cells(False)}; {records} records of "
         f"{PAYLOAD} registers, {len(seeds)} seed(s), one station, window 1, write range listed "
         f"first; cosim: the line's character time in virtual time, realistic radio 9600 bit/s, "
         f"10 ms scans; bound at 19200 with window 1: {min(1, 1000 / tcp / bound):.2f} (a record "
         f"and its acknowledgement cross both lines in series with the radio, at least "
         f"{bound:.0f} ms per record against TCP's {1000 / tcp:.0f} ms; docs/serial.md); "
         f"target >= 0.9 at 19200)", "OK" if r >= 0.9 else "MISSED")


def fig_fc23_gain(quick, workdir):
    """Records/s with the device option fc23 (a pending read and write of a device as one FC23)
    against FC16 + FC3, on RTU 19200 8E1; records of 121 registers (an FC23 writes at most 121)."""
    import mipcosim.sim as S
    name = "fc23_gain"
    if cosim_missing(name, pending=False):
        return
    records = 30 if quick else 120
    seeds = [1] if quick else [1, 2]
    try:
        g = {}
        for sf in (False, True):
            for f in (False, True):
                g[(sf, f)] = statistics.mean(
                    records_per_s(19200, records, seed, workdir, status_first=sf, fc23=f,
                                  payload=PAYLOAD - 2) for seed in seeds)
    except Exception as e:  # noqa: BLE001 - report, go on with the other figures
        error(name, failure(e))
        return
    whole = g[(False, True)] / g[(False, False)]
    first = g[(True, True)] / g[(True, False)]
    # the most FC23 could give: each of a record's two writes (record, acknowledgement) saves
    # one answer and one request header with their gaps, less FC23's 4 longer header characters
    # (12 characters + 2 gaps); even if each saving brought its write a whole radio slot
    # earlier (an empty slot: two telegrams without a block and two gaps) - and it brings none:
    # a write follows the read it answers, FC23 does its write first
    radio = S.Radio.realistic()
    slot = 2 * (radio.overhead_bytes * 8_000 / radio.bitrate + radio.slot_gap_ns / MS)
    saved = 12 * rtu_char_ms(19200) + 2 * rtu_gap_ms(19200)
    cycle = 1000 / g[(False, False)]
    line(name, f"{whole:.2f} (records/s with FC23 / with FC16 + FC3 at 19200 baud 8E1: reading the "
         f"whole area {g[(False, True)]:.2f}/{g[(False, False)]:.2f}/s = {whole:.2f}, status_first "
         f"{g[(True, True)]:.2f}/{g[(True, False)]:.2f}/s = {first:.2f}; {records} records of "
         f"{PAYLOAD - 2} registers, {len(seeds)} seed(s); cosim: the line's character time in "
         f"virtual time, realistic radio; bound {cycle / (cycle - 2 * slot):.2f}: FC23 saves one "
         f"turnaround, {saved:.0f} ms of line, per write, none of it on the critical path (each "
         f"of a record's 2 writes answers the read before it, and FC23 writes before it reads); "
         f"even a whole {slot:.0f} ms radio slot per write would leave {cycle - 2 * slot:.0f} of "
         f"{cycle:.0f} ms; docs/serial.md; target >= 1.2)", "OK" if whole >= 1.2 else "MISSED")
