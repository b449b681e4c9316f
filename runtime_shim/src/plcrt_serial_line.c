/* An RTU exchange's time on the wire in virtual time (the co-simulation): see below. */
#include "plcrt_serial_line.h"
#include "plcrt_transport.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* ---- serial line in virtual time
 * In virtual mode an RTU device's exchange takes the time it takes on the wire: the request is
 * taken at t, reaches the slave (the transport, the emulator core) when its last character has
 * crossed the line, t + (request characters) x (character time); the answer follows one
 * 3.5-character gap later and is shown when its last character has arrived; the next request on
 * the line waits one more gap (and the device's pause). The devices on one line take it in turn.
 * A character is 1 start + data + parity + stop bits; the gap is 1.75 ms above 19200 baud. In
 * real time the line itself takes that time. */

static uint64_t char_ns(const plcrt_device_t *o)
{
    int bits = 1 + o->data_bits + (o->parity != 'N') + o->stop_bits;
    return (uint64_t)bits * 1000000000ull / (uint64_t)(o->baud > 0 ? o->baud : 19200);
}

static uint64_t gap_ns(const plcrt_device_t *o)
{
    return o->baud > 19200 ? 1750000ull : char_ns(o) * 7 / 2;
}

/* RTU frame lengths (unit id + PDU + CRC) of a request and of its answer */
static int rtu_req_chars(const request_t *q)
{
    if (q->fc == 16) return 9 + 2 * q->count;
    if (q->fc == 15) return 9 + (q->count + 7) / 8;
    if (q->fc == 23) return 13 + 2 * q->wcount;
    return 8;
}

static int rtu_rsp_chars(const request_t *q, int status)
{
    if (status > 0 && status < 1000) return 5; /* exception */
    if (q->status_first) return 5 + 2 * (q->status_first < q->count ? q->status_first : q->count); /* the first exchange */
    if (q->fc == 3 || q->fc == 4 || q->fc == 23) return 5 + 2 * q->count;
    if (q->fc == 1 || q->fc == 2) return 5 + (q->count + 7) / 8;
    return 8;
}

int plcrt_line_modelled(plcrt_t *rt, const plcrt_device_t *d) { return d->rtu && !plcrt_threaded(rt); }

/* moves the exchange on the line of owner o on to now; returns 1 while the line is busy */
int plcrt_line_advance(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *o, uint64_t now)
{
    if (o->line_range < 0) return now < o->line_free_ns;
    plcrt_range_t *r = &m->ranges[o->line_range];
    plcrt_device_t *d = &m->devices[r->dev];
    request_t *q = o->line_req;
    if (o->line_phase == 1) {
        if (now < o->line_send_ns) return 1;
        /* the request is complete at the slave: the transport answers now */
        request_t *w = &m->q;
        memcpy(w, q, sizeof *w);
        int status = plcrt_range_request(rt, m, r, w, o->line_send_ns);
        if (status < 0) status = STATUS_TRANSPORT(ENOTCONN);
        memcpy(q, w, sizeof *q);
        o->line_status = status;
        o->line_phase = 2;
        if (q->unit == 0)
            o->line_done_ns = o->line_send_ns; /* broadcast: no answer */
        else if (status >= 1000)
            o->line_done_ns = o->line_send_ns + d->timeout_ns; /* silence: the master waits its timeout */
        else
            o->line_done_ns = o->line_send_ns + gap_ns(o) + (uint64_t)rtu_rsp_chars(q, status) * char_ns(o);
        if (q->extra_req) /* status_first's further exchanges, one after the other */
            o->line_done_ns += (uint64_t)(q->extra_req + q->extra_rsp) * char_ns(o) +
                               (uint64_t)(q->extra_req / 8) * 2 * gap_ns(o);
    }
    if (now < o->line_done_ns) return 1;
    plcrt_range_publish(m, r, q, o->line_status);
    if (o->line_range2 >= 0) plcrt_range_publish(m, &m->ranges[o->line_range2], q, o->line_status);
    o->line_range2 = -1;
    o->line_busy_ns += o->line_done_ns - (o->line_send_ns - (uint64_t)rtu_req_chars(q) * char_ns(o));
    o->line_free_ns = o->line_done_ns + gap_ns(o) + (d->pause_ns > o->pause_ns ? d->pause_ns : o->pause_ns);
    o->line_range = -1;
    return now < o->line_free_ns;
}

/* puts request q of range r on the idle line of owner o. A trigger request starts where the
 * real-time master would start it: when the scan that raised the trigger ended (one tick before
 * this I/O phase; scans take no virtual time), or when the line became free after that; a
 * poll of a cycle / change range starts now. An exchange shorter than the rest of the tick then
 * shows in this scan, as over TCP, and as in real time when it fits into the idle time. */
int plcrt_line_start(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *o, plcrt_range_t *r,
                      const request_t *q, uint64_t now, int pair)
{
    uint64_t start = now;
    if (r->policy == POLICY_TRIGGER) {
        start = now >= rt->tick_ns ? now - rt->tick_ns : 0;
        if (start < o->line_free_ns) start = o->line_free_ns;
    }
    o->line_range2 = pair;
    if (!o->line_req && !(o->line_req = malloc(sizeof *o->line_req))) return -1;
    memcpy(o->line_req, q, sizeof *q);
    o->line_range = (int)(r - m->ranges);
    o->line_phase = 1;
    o->line_send_ns = start + (uint64_t)rtu_req_chars(q) * char_ns(o);
    return 0;
}

