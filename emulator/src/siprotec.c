/* The SIPROTEC event recorder core. Facts and choices: docs/chain.md, "The relay (SIPROTEC event
 * recorder)". In short:
 *   base+0  number of event-recorder entries not yet read (acknowledged)
 *   base+1  SOE_Control: bits 0..seq_bits-1 sequence number, bits 8..13 number of message
 *           blocks, bit 14 "Start GS" (always 0), bit 15 "reset list"
 *   base+2 + 8*i  message block i (0..2): type/bit offset, address, cause/type, value,
 *           time stamp (4 registers: ms since 1970 UTC, most significant first)
 * The offered blocks (the "window") are frozen until an acknowledgement or a reset changes them;
 * every new window gets the next sequence number. */
#include "siprotec.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct entry {
    uint16_t w[4];
    uint64_t ts_ms;
} entry_t;

typedef struct scripted {
    uint64_t t;
    uint16_t w[4];
} scripted_t;

struct siprotec_relay {
    siprotec_config c;
    entry_t *ring;
    uint32_t head, count;   /* oldest entry at ring[head] */
    uint16_t win;           /* entries offered (the oldest win) */
    int frozen;             /* a read has shown the offered blocks: unchanged until acknowledged */
    uint16_t seq;
    uint64_t now;
    /* event sources */
    scripted_t *script;
    size_t n_script, cap_script, next_script;
    uint64_t n_periodic, n_bursts, n_synth;
    siprotec_stats st;
};

void siprotec_config_default(siprotec_config *c)
{
    memset(c, 0, sizeof *c);
    c->base = 600;
    c->capacity = 200;
    c->overflow = SIPROTEC_OVF_DROP_OLDEST;
    c->seq_bits = 8;
    c->bad_ack = SIPROTEC_BAD_ACK_EXC03;
    c->burst_every_s = 1.0;
}

siprotec_relay *siprotec_new(const siprotec_config *c, char *err, size_t errlen)
{
    const char *why = NULL;
    if (c->base > 65535 - SIPROTEC_MAP_REGS + 1)
        why = "base leaves no room for the 26 registers";
    else if (c->capacity < SIPROTEC_BLOCKS || c->capacity > 1000000)
        why = "capacity must be 3..1000000";
    else if (c->overflow != SIPROTEC_OVF_DROP_OLDEST && c->overflow != SIPROTEC_OVF_DROP_NEW)
        why = "overflow must be drop-oldest or drop-new";
    else if (c->seq_bits < 2 || c->seq_bits > 8)
        why = "seq_bits must be 2..8";
    else if (c->bad_ack != SIPROTEC_BAD_ACK_EXC03 && c->bad_ack != SIPROTEC_BAD_ACK_IGNORE)
        why = "bad_ack must be exc03 or ignore";
    else if (!(c->rate >= 0 && c->rate <= 1e6))
        why = "rate must be 0..1000000 events/s";
    else if (c->burst_n > 0 && !(c->burst_every_s >= 0.001 && c->burst_every_s <= 1e6))
        why = "burst period must be 0.001..1000000 s";
    else if (c->burst_n > 1000000)
        why = "burst size must be 0..1000000";
    if (why) {
        if (err && errlen)
            snprintf(err, errlen, "%s", why);
        return NULL;
    }
    siprotec_relay *r = calloc(1, sizeof *r);
    if (r)
        r->ring = calloc(c->capacity, sizeof *r->ring);
    if (!r || !r->ring) {
        free(r);
        if (err && errlen)
            snprintf(err, errlen, "out of memory");
        return NULL;
    }
    r->c = *c;
    return r;
}

void siprotec_free(siprotec_relay *r)
{
    if (!r)
        return;
    free(r->ring);
    free(r->script);
    free(r);
}

static uint16_t seq_max(const siprotec_relay *r) { return (uint16_t)((1u << r->c.seq_bits) - 1); }

/* 1, 2, ..., max, 1, ...: 0 is never shown with data (writing 0 means "reset without data") */
static void seq_raise(siprotec_relay *r) { r->seq = (uint16_t)(r->seq % seq_max(r) + 1); }

/* Offers up to 3 entries. A new offer gets the next sequence number; an offer no read has shown
 * yet may still grow (our choice: the manual only says that what the master read stays). */
static void latch(siprotec_relay *r)
{
    if (r->frozen || r->win == r->count || r->win == SIPROTEC_BLOCKS)
        return;
    if (r->win == 0)
        seq_raise(r);
    r->win = (uint16_t)(r->count < SIPROTEC_BLOCKS ? r->count : SIPROTEC_BLOCKS);
}

static entry_t *at(siprotec_relay *r, uint32_t i) { return &r->ring[(r->head + i) % r->c.capacity]; }

static void record(siprotec_relay *r, uint64_t t, const uint16_t w[4])
{
    r->st.generated++;
    if (r->count == r->c.capacity) {
        if (r->c.overflow == SIPROTEC_OVF_DROP_NEW || r->win >= r->count) {
            r->st.dropped++;
            return;
        }
        /* drop the oldest entry not offered: the offered ones must not change */
        for (uint32_t i = r->win; i > 0; i--)
            *at(r, i) = *at(r, i - 1);
        r->head = (r->head + 1) % r->c.capacity;
        r->count--;
        r->st.dropped++;
    }
    entry_t *e = at(r, r->count);
    memcpy(e->w, w, sizeof e->w);
    e->ts_ms = r->c.time_origin_ms + t / 1000000u;
    r->count++;
    latch(r);
}

/* generated event n (our choice, docs/chain.md): a single-point indication in the input-status
 * area, bit n mod 16 of register 1 + (n / 16) mod 64, cause 1 / type 1, value n + 1 */
static void synth(siprotec_relay *r, uint64_t t)
{
    uint64_t n = r->n_synth++;
    uint16_t w[4] = { (uint16_t)(0x0100 | (n % 16)), (uint16_t)(1 + (n / 16) % 64), 0x0101,
                      (uint16_t)(n + 1) };
    record(r, t, w);
}

static uint64_t t_periodic(const siprotec_relay *r, uint64_t k)
{
    return (uint64_t)((double)(k + 1) * 1e9 / r->c.rate);
}

static uint64_t t_burst(const siprotec_relay *r, uint64_t k)
{
    return (uint64_t)((double)(k + 1) * r->c.burst_every_s * 1e9);
}

uint64_t siprotec_next_event(const siprotec_relay *r)
{
    uint64_t t = UINT64_MAX;
    if (r->next_script < r->n_script)
        t = r->script[r->next_script].t;
    if (r->c.rate > 0 && t_periodic(r, r->n_periodic) < t)
        t = t_periodic(r, r->n_periodic);
    if (r->c.burst_n > 0 && t_burst(r, r->n_bursts) < t)
        t = t_burst(r, r->n_bursts);
    return t;
}

int siprotec_script(siprotec_relay *r, uint64_t t_ns, const uint16_t w[4])
{
    if (r->n_script == r->cap_script) {
        size_t nc = r->cap_script ? 2 * r->cap_script : 16;
        scripted_t *p = realloc(r->script, nc * sizeof *p);
        if (!p)
            return -1;
        r->script = p;
        r->cap_script = nc;
    }
    if (t_ns < r->now)
        t_ns = r->now; /* the past is gone: it happens at the next advance */
    /* keep the pending part sorted by time, equal times in the order given */
    size_t i = r->n_script;
    while (i > r->next_script && r->script[i - 1].t > t_ns) {
        r->script[i] = r->script[i - 1];
        i--;
    }
    r->script[i].t = t_ns;
    memcpy(r->script[i].w, w, sizeof r->script[i].w);
    r->n_script++;
    return 0;
}

void siprotec_advance(siprotec_relay *r, uint64_t now_ns)
{
    if (now_ns < r->now)
        return;
    r->now = now_ns;
    for (;;) {
        uint64_t t = siprotec_next_event(r);
        if (t > now_ns)
            break;
        /* at equal times: scripted, then periodic, then a burst */
        if (r->next_script < r->n_script && r->script[r->next_script].t == t) {
            record(r, t, r->script[r->next_script].w);
            r->next_script++;
        } else if (r->c.rate > 0 && t_periodic(r, r->n_periodic) == t) {
            r->n_periodic++;
            synth(r, t);
        } else {
            r->n_bursts++;
            for (uint32_t k = 0; k < r->c.burst_n; k++)
                synth(r, t);
        }
    }
    /* drop the events that happened, so a caller scripting as it goes keeps a small array */
    if (r->next_script > 0 && r->next_script >= r->n_script / 2) {
        memmove(r->script, r->script + r->next_script, (r->n_script - r->next_script) * sizeof *r->script);
        r->n_script -= r->next_script;
        r->next_script = 0;
    }
}

static uint16_t reg(const siprotec_relay *r, unsigned off)
{
    if (off == 0)
        return (uint16_t)(r->count > 65535 ? 65535 : r->count);
    if (off == 1)
        return (uint16_t)(r->seq | (unsigned)r->win << 8);
    unsigned b = (off - 2) / SIPROTEC_BLOCK_REGS, k = (off - 2) % SIPROTEC_BLOCK_REGS;
    if (b >= r->win)
        return 0;
    const entry_t *e = &r->ring[(r->head + b) % r->c.capacity];
    if (k < 4)
        return e->w[k];
    return (uint16_t)(e->ts_ms >> (16 * (7 - k)));
}

void siprotec_peek(const siprotec_relay *r, uint16_t addr, unsigned n, uint16_t *out)
{
    for (unsigned i = 0; i < n; i++) {
        unsigned a = (unsigned)addr + i;
        out[i] = a >= r->c.base && a < (unsigned)r->c.base + SIPROTEC_MAP_REGS ? reg(r, a - r->c.base) : 0;
    }
}

void siprotec_get_stats(const siprotec_relay *r, siprotec_stats *s)
{
    *s = r->st;
    s->entries = r->count;
    s->seq = r->seq;
    s->offered = r->win;
}

/* A write of v into SOE_Control: 0 accepted, 3 refused (nothing changed). */
static int soe_write(siprotec_relay *r, uint16_t v)
{
    uint16_t seq = (uint16_t)(v & 0xFF), n = (uint16_t)((v >> 8) & 0x3F);
    int reset = (v & 0x8000) != 0;
    /* bit 14 "Start GS" is always 0 when read; a 1 written there is ignored (our choice) */
    if (seq == 0 && reset && n == 0) {
        /* reset without data (SIPROTEC 5 manual 5.2): sequence number 0 with bit 15 */
        r->st.reset_cleared += r->count;
        r->head = r->count = 0;
        r->win = 0;
        r->frozen = 0;
        return 0;
    }
    if (seq == 0 || seq > seq_max(r) || r->win == 0 || seq != r->seq || n > r->win) {
        r->st.bad_acks++;
        return r->c.bad_ack == SIPROTEC_BAD_ACK_EXC03 ? 3 : 0;
    }
    if (n > 0) {
        r->head = (r->head + n) % r->c.capacity;
        r->count -= n;
        r->st.acknowledged += n;
        r->win = 0;
        r->frozen = 0;
    }
    if (reset) {
        r->st.reset_cleared += r->count;
        r->head = r->count = 0;
        r->win = 0;
        r->frozen = 0;
    }
    latch(r);
    return 0;
}

static long answer(const uint8_t *req, uint8_t *resp, const uint8_t *pdu, size_t plen)
{
    memcpy(resp, req, 4);
    resp[4] = (uint8_t)((plen + 1) >> 8);
    resp[5] = (uint8_t)(plen + 1);
    resp[6] = req[6];
    memcpy(resp + 7, pdu, plen);
    return (long)(7 + plen);
}

static long exc(const uint8_t *req, uint8_t *resp, uint8_t code)
{
    uint8_t p[2] = { (uint8_t)(req[7] | 0x80), code };
    return answer(req, resp, p, 2);
}

long siprotec_handle(siprotec_relay *r, const uint8_t *req, size_t len, uint8_t *resp, size_t cap)
{
    if (!req || !resp || cap < SIPROTEC_RESPONSE_MAX || len < 8)
        return -1;
    size_t mlen = (size_t)req[4] << 8 | req[5];
    if (req[2] || req[3] || mlen < 2 || mlen != len - 6)
        return -1;
    const uint8_t *p = req + 7;
    size_t plen = len - 7;
    unsigned fc = p[0];
    if (fc != 3 && fc != 6 && fc != 16)
        return exc(req, resp, 1);
    unsigned a = plen >= 3 ? (unsigned)(p[1] << 8 | p[2]) : 0;
    unsigned q = 0;
    if (fc == 3) {
        if (plen != 5)
            return exc(req, resp, 3);
        q = (unsigned)(p[3] << 8 | p[4]);
        if (q < 1 || q > 125)
            return exc(req, resp, 3);
    } else if (fc == 6) {
        if (plen != 5)
            return exc(req, resp, 3);
        q = 1;
    } else {
        if (plen < 6)
            return exc(req, resp, 3);
        q = (unsigned)(p[3] << 8 | p[4]);
        if (q < 1 || q > 123 || p[5] != 2 * q || plen != 6 + 2 * q)
            return exc(req, resp, 3);
    }
    if (a < r->c.base || a + q > (unsigned)r->c.base + SIPROTEC_MAP_REGS)
        return exc(req, resp, 2);
    if (fc == 3) {
        /* what a read shows of SOE_Control or the blocks stays until acknowledged */
        if (a + q > (unsigned)r->c.base + 1 && r->win > 0)
            r->frozen = 1;
        uint8_t out[2 + 2 * 125];
        out[0] = 3;
        out[1] = (uint8_t)(2 * q);
        for (unsigned i = 0; i < q; i++) {
            uint16_t v = reg(r, a - r->c.base + i);
            out[2 + 2 * i] = (uint8_t)(v >> 8);
            out[3 + 2 * i] = (uint8_t)v;
        }
        return answer(req, resp, out, 2 + 2 * q);
    }
    /* only SOE_Control is writable; a write to the others: exception 03 (SIPROTEC 4 bus mapping
     * 7UM62, C53000-L1840-C009-03, section 3.4.8) */
    if (a != (unsigned)r->c.base + 1 || q != 1)
        return exc(req, resp, 3);
    const uint8_t *v = fc == 6 ? p + 3 : p + 6;
    int e = soe_write(r, (uint16_t)(v[0] << 8 | v[1]));
    if (e)
        return exc(req, resp, (uint8_t)e);
    return answer(req, resp, p, 5); /* FC6 echoes the request; FC16 address and quantity */
}
