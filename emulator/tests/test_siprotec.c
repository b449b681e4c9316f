/* Unit tests of the SIPROTEC event recorder core through raw Modbus TCP frames: the register map,
 * the SOE_Control handshake, reset list, overflow, write protection and hostile input. */
#include "siprotec.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define UNIT_CLASS "emulator.siprotec"
#include "unit.h"
#include "pdu.h"

static uint8_t g_resp[SIPROTEC_RESPONSE_MAX];
static long g_rlen;

static long send_pdu(siprotec_relay *r, const uint8_t *pdu, size_t plen)
{
    uint8_t req[300];
    req[0] = 0x12; req[1] = 0x34; req[2] = 0; req[3] = 0;
    req[4] = (uint8_t)((plen + 1) >> 8); req[5] = (uint8_t)(plen + 1);
    req[6] = 1;
    memcpy(req + 7, pdu, plen);
    g_rlen = siprotec_handle(r, req, plen + 7, g_resp, sizeof g_resp);
    return g_rlen;
}

/* exception code, or 0 with the values in vals */
static int rd(siprotec_relay *r, unsigned fc, unsigned a, unsigned q, uint16_t *vals)
{
    uint8_t p[5] = { (uint8_t)fc, (uint8_t)(a >> 8), (uint8_t)a, (uint8_t)(q >> 8), (uint8_t)q };
    if (send_pdu(r, p, 5) < 9)
        return -1;
    return pdu_read_reply(g_resp, g_rlen, q, vals);
}

static int wr6(siprotec_relay *r, unsigned a, uint16_t v)
{
    uint8_t p[5] = { 6, (uint8_t)(a >> 8), (uint8_t)a, (uint8_t)(v >> 8), (uint8_t)v };
    if (send_pdu(r, p, 5) < 9)
        return -1;
    if (g_resp[7] & 0x80)
        return g_resp[8];
    return memcmp(g_resp + 7, p, 5) == 0 ? 0 : -2;
}

static int wr16(siprotec_relay *r, unsigned a, unsigned q, const uint16_t *vals)
{
    uint8_t p[6 + 2 * 130];
    if (send_pdu(r, p, pdu_write_regs(p, a, q, vals)) < 9)
        return -1;
    return g_resp[7] & 0x80 ? g_resp[8] : 0;
}

static siprotec_relay *mk(void (*tweak)(siprotec_config *))
{
    siprotec_config c;
    siprotec_config_default(&c);
    c.time_origin_ms = 1767225600000ull; /* 2026-01-01T00:00:00Z */
    if (tweak)
        tweak(&c);
    char err[128];
    siprotec_relay *r = siprotec_new(&c, err, sizeof err);
    if (!r)
        fprintf(stderr, "siprotec_new: %s\n", err);
    return r;
}

/* scripted event k (1-based) at k ms: value k, address 100 + k */
static void script_n(siprotec_relay *r, int from, int to)
{
    for (int k = from; k <= to; k++) {
        uint16_t w[4] = { 0x0102, (uint16_t)(100 + k), 0x0101, (uint16_t)k };
        siprotec_script(r, (uint64_t)k * 1000000u, w);
    }
}

#define SOE(seq, n) ((uint16_t)((seq) | (n) << 8))
enum { B = 600 };

static void t_empty_map(void)
{
    siprotec_relay *r = mk(NULL);
    uint16_t v[26];
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    for (int i = 0; i < 26; i++)
        CHECK_EQ(v[i], 0);
    CHECK_EQ(rd(r, 3, B - 1, 1, v), 2);
    CHECK_EQ(rd(r, 3, B + 25, 2, v), 2);
    CHECK_EQ(rd(r, 3, B + 25, 1, v), 0);
    CHECK_EQ(rd(r, 4, B, 2, v), 1);   /* holding registers only */
    siprotec_free(r);
}

static void t_handshake(void)
{
    siprotec_relay *r = mk(NULL);
    script_n(r, 1, 5);
    siprotec_advance(r, 10000000);
    uint16_t v[26], again[26];
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[0], 5);
    CHECK_EQ(v[1], SOE(1, 3));
    for (int b = 0; b < 3; b++) {
        CHECK_EQ(v[2 + 8 * b], 0x0102);
        CHECK_EQ(v[3 + 8 * b], 101 + b);
        CHECK_EQ(v[4 + 8 * b], 0x0101);
        CHECK_EQ(v[5 + 8 * b], 1 + b);
        unsigned long long ts = (unsigned long long)v[6 + 8 * b] << 48 | (unsigned long long)v[7 + 8 * b] << 32 |
                                (unsigned long long)v[8 + 8 * b] << 16 | v[9 + 8 * b];
        CHECK_EQ(ts, 1767225600000ull + 1 + (unsigned)b);
    }
    /* a repeated read (the first answer lost) gives the same data */
    CHECK_EQ(rd(r, 3, B, 26, again), 0);
    CHECK(memcmp(v, again, sizeof v) == 0);
    /* acknowledge 3 with sequence number 1: deleted, sequence number raised */
    CHECK_EQ(wr6(r, B + 1, SOE(1, 3)), 0);
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[0], 2);
    CHECK_EQ(v[1], SOE(2, 2));
    CHECK_EQ(v[5], 4);
    CHECK_EQ(v[13], 5);
    CHECK_EQ(v[18], 0); /* block 3 empty */
    /* FC16 works as well */
    CHECK_EQ(wr16(r, B + 1, 1, (uint16_t[]){ SOE(2, 2) }), 0);
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[0], 0);
    CHECK_EQ(v[1], SOE(2, 0));
    /* the next entry: a raised sequence number */
    script_n(r, 6, 6);
    siprotec_advance(r, 10000000);
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[0], 1);
    CHECK_EQ(v[1], SOE(3, 1));
    siprotec_stats s;
    siprotec_get_stats(r, &s);
    CHECK_EQ(s.acknowledged, 5);
    CHECK_EQ(s.generated, 6);
    siprotec_free(r);
}

static void t_frozen_until_ack(void)
{
    siprotec_relay *r = mk(NULL);
    script_n(r, 1, 1);
    siprotec_advance(r, 1000000);
    uint16_t v[26], w[26];
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[1], SOE(1, 1));
    script_n(r, 2, 4);
    siprotec_advance(r, 5000000);
    CHECK_EQ(rd(r, 3, B, 26, w), 0);
    CHECK_EQ(w[0], 4);                      /* the count shows the newcomers ... */
    CHECK(memcmp(v + 1, w + 1, 25 * 2) == 0); /* ... the handshake and blocks do not change */
    CHECK_EQ(wr6(r, B + 1, SOE(1, 1)), 0);
    CHECK_EQ(rd(r, 3, B, 26, w), 0);
    CHECK_EQ(w[1], SOE(2, 3));
    CHECK_EQ(w[5], 2);
    siprotec_free(r);
}

static void t_partial_ack(void)
{
    siprotec_relay *r = mk(NULL);
    script_n(r, 1, 3);
    siprotec_advance(r, 3000000);
    uint16_t v[26];
    CHECK_EQ(wr6(r, B + 1, SOE(1, 1)), 0);
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[0], 2);
    CHECK_EQ(v[1], SOE(2, 2));
    CHECK_EQ(v[5], 2);
    /* acknowledging 0 entries changes nothing */
    CHECK_EQ(wr6(r, B + 1, SOE(2, 0)), 0);
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[1], SOE(2, 2));
    siprotec_free(r);
}

static void t_bad_acks(void)
{
    siprotec_relay *r = mk(NULL);
    uint16_t v[26], w[26];
    CHECK_EQ(wr6(r, B + 1, SOE(1, 0)), 3);    /* nothing offered */
    script_n(r, 1, 4);
    siprotec_advance(r, 4000000);
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(wr6(r, B + 1, SOE(2, 3)), 3);    /* wrong sequence number */
    CHECK_EQ(wr6(r, B + 1, SOE(1, 4)), 3);    /* more than offered */
    CHECK_EQ(wr6(r, B + 1, SOE(0, 1)), 3);    /* sequence number 0 without reset */
    CHECK_EQ(wr6(r, B + 1, SOE(1, 63)), 3);
    CHECK_EQ(rd(r, 3, B, 26, w), 0);
    CHECK(memcmp(v, w, sizeof v) == 0);
    /* the same acknowledgement twice: the second has an old sequence number */
    CHECK_EQ(wr6(r, B + 1, SOE(1, 3)), 0);
    CHECK_EQ(wr6(r, B + 1, SOE(1, 3)), 3);
    CHECK_EQ(rd(r, 3, B, 2, w), 0);
    CHECK_EQ(w[0], 1);
    siprotec_stats s;
    siprotec_get_stats(r, &s);
    CHECK_EQ(s.bad_acks, 6);
    siprotec_free(r);
}

static void ignore_bad(siprotec_config *c) { c->bad_ack = SIPROTEC_BAD_ACK_IGNORE; }

static void t_bad_ack_ignored(void)
{
    siprotec_relay *r = mk(ignore_bad);
    script_n(r, 1, 2);
    siprotec_advance(r, 2000000);
    uint16_t v[2];
    CHECK_EQ(wr6(r, B + 1, SOE(7, 2)), 0);    /* answered normally ... */
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[0], 2);                         /* ... nothing deleted */
    CHECK_EQ(v[1], SOE(1, 2));
    siprotec_free(r);
}

static void t_reset_list(void)
{
    siprotec_relay *r = mk(NULL);
    script_n(r, 1, 5);
    siprotec_advance(r, 5000000);
    uint16_t v[26];
    /* with the acknowledgement: everything goes, the sequence number is not reset */
    CHECK_EQ(wr6(r, B + 1, (uint16_t)(SOE(1, 3) | 0x8000)), 0);
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[0], 0);
    CHECK_EQ(v[1], SOE(1, 0));
    script_n(r, 6, 7);
    siprotec_advance(r, 7000000);
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[1], SOE(2, 2));
    /* without data: sequence number 0 with bit 15 */
    CHECK_EQ(wr6(r, B + 1, 0x8000), 0);
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[0], 0);
    CHECK_EQ(v[1], SOE(2, 0));
    CHECK_EQ(v[5], 0);
    script_n(r, 8, 8);
    siprotec_advance(r, 8000000);
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[1], SOE(3, 1));
    /* bit 14 ("Start GS", always 0) is never shown */
    CHECK_EQ(v[1] & 0x4000, 0);
    siprotec_stats s;
    siprotec_get_stats(r, &s);
    CHECK_EQ(s.acknowledged, 3);   /* the first three by the acknowledgement, then 2 + 2 cleared */
    CHECK_EQ(s.reset_cleared, 4);
    siprotec_free(r);
}

static void cap5(siprotec_config *c) { c->capacity = 5; }
static void cap5_new(siprotec_config *c) { c->capacity = 5; c->overflow = SIPROTEC_OVF_DROP_NEW; }

static uint16_t drain_values(siprotec_relay *r, uint16_t *vals)
{
    uint16_t n = 0, v[26];
    while (rd(r, 3, B, 26, v) == 0 && (v[1] >> 8) > 0) {
        unsigned k = v[1] >> 8;
        for (unsigned b = 0; b < k; b++)
            vals[n++] = v[5 + 8 * b];
        if (wr6(r, B + 1, v[1]) != 0)
            break;
    }
    return n;
}

static void t_overflow(void)
{
    siprotec_relay *r = mk(cap5);
    script_n(r, 1, 8);
    siprotec_advance(r, 8000000);
    uint16_t vals[16];
    siprotec_stats s;
    siprotec_get_stats(r, &s);
    CHECK_EQ(s.entries, 5);
    CHECK_EQ(s.dropped, 3);
    /* the offered 1..3 stay, the oldest of the rest go */
    uint16_t n = drain_values(r, vals);
    CHECK_EQ(n, 5);
    uint16_t want[5] = { 1, 2, 3, 7, 8 };
    for (int i = 0; i < 5 && i < n; i++)
        CHECK_EQ(vals[i], want[i]);
    siprotec_free(r);

    r = mk(cap5_new);
    script_n(r, 1, 8);
    siprotec_advance(r, 8000000);
    n = drain_values(r, vals);
    CHECK_EQ(n, 5);
    for (int i = 0; i < 5 && i < n; i++)
        CHECK_EQ(vals[i], i + 1);
    siprotec_free(r);
}

static void t_write_protect(void)
{
    siprotec_relay *r = mk(NULL);
    script_n(r, 1, 2);
    siprotec_advance(r, 2000000);
    CHECK_EQ(wr6(r, B, 0), 3);                 /* the count */
    CHECK_EQ(wr6(r, B + 2, 0), 3);             /* a message block */
    CHECK_EQ(wr16(r, B + 1, 2, (uint16_t[]){ SOE(1, 2), 0 }), 3);
    CHECK_EQ(wr16(r, B, 2, (uint16_t[]){ 0, SOE(1, 2) }), 3);
    CHECK_EQ(wr6(r, B + 26, 0), 2);            /* outside the map */
    CHECK_EQ(wr6(r, 0, 0), 2);
    uint16_t v[2];
    CHECK_EQ(rd(r, 3, B, 2, v), 0);
    CHECK_EQ(v[0], 2);
    CHECK_EQ(v[1], SOE(1, 2));
    siprotec_free(r);
}

static void base0(siprotec_config *c) { c->base = 0; }

static void t_base(void)
{
    siprotec_relay *r = mk(base0);
    script_n(r, 1, 1);
    siprotec_advance(r, 1000000);
    uint16_t v[2];
    CHECK_EQ(rd(r, 3, 0, 2, v), 0);
    CHECK_EQ(v[1], SOE(1, 1));
    CHECK_EQ(rd(r, 3, 600, 2, v), 2);
    CHECK_EQ(wr6(r, 1, SOE(1, 1)), 0);
    siprotec_free(r);
}

static void rate_burst(siprotec_config *c) { c->rate = 10; c->burst_n = 4; c->burst_every_s = 0.5; }

static void t_sources(void)
{
    siprotec_relay *r = mk(rate_burst);
    CHECK_EQ(siprotec_next_event(r), 100000000);
    siprotec_advance(r, 999999999);
    siprotec_stats s;
    siprotec_get_stats(r, &s);
    CHECK_EQ(s.generated, 9 + 4);
    siprotec_advance(r, 1000000000);
    siprotec_get_stats(r, &s);
    CHECK_EQ(s.generated, 10 + 8);
    uint16_t v[26];
    CHECK_EQ(rd(r, 3, B, 26, v), 0);
    CHECK_EQ(v[0], 18);
    /* the first generated event: at 100 ms, bit 0 of input-status register 1, value 1 */
    CHECK_EQ(v[2], 0x0100);
    CHECK_EQ(v[3], 1);
    CHECK_EQ(v[5], 1);
    CHECK_EQ(v[9], (1767225600000ull + 100) & 0xFFFF);
    siprotec_free(r);
}

/* events scripted out of order and while time runs come out in time order; one scripted for a
 * time already past happens at the time reached (its time stamp says so) */
static void t_script_order(void)
{
    siprotec_relay *r = mk(NULL);
    uint16_t w[4] = { 1, 1, 1, 0 };
    uint16_t v[26];
    for (uint64_t k = 0; k < 40; k++) {  /* many rounds on one relay, across the dropping of consumed events */
        uint64_t t = k * 10000000u;
        w[3] = 5; siprotec_script(r, t + 5000000, w);
        w[3] = 3; siprotec_script(r, t + 3000000, w);
        siprotec_advance(r, t + 2000000);
        w[3] = 4; siprotec_script(r, t + 4000000, w);
        w[3] = 1; siprotec_script(r, t + 1000000, w); /* past: happens at t + 2 ms */
        siprotec_advance(r, t + 9000000);
        CHECK_EQ(rd(r, 3, B, 26, v), 0);
        CHECK_EQ(v[0], 4);
        CHECK_EQ(v[5], 1);
        CHECK_EQ(v[9], (1767225600000ull + t / 1000000 + 2) & 0xFFFF);
        CHECK_EQ(v[13], 3);
        CHECK_EQ(v[21], 4);
        CHECK_EQ(wr6(r, B + 1, v[1]), 0);
        CHECK_EQ(rd(r, 3, B, 6, v), 0);
        CHECK_EQ(v[5], 5);
        CHECK_EQ(wr6(r, B + 1, v[1]), 0);
    }
    siprotec_free(r);
}

static void seq2(siprotec_config *c) { c->seq_bits = 2; }

static void t_seq_wrap(void)
{
    siprotec_relay *r = mk(seq2);
    script_n(r, 1, 5);
    siprotec_advance(r, 5000000);
    uint16_t want[5] = { 1, 2, 3, 1, 2 }, v[2];
    for (int i = 0; i < 5; i++) {   /* one entry acknowledged at a time: a new offer each */
        CHECK_EQ(rd(r, 3, B, 2, v), 0);
        CHECK_EQ(v[1] & 0xFF, want[i]);
        CHECK_EQ(wr6(r, B + 1, SOE(want[i], 1)), 0);
    }
    siprotec_free(r);
}

static void t_bad_config(void)
{
    siprotec_config c;
    char err[128];
    siprotec_config_default(&c); c.capacity = 2;
    CHECK(siprotec_new(&c, err, sizeof err) == NULL);
    CHECK(strstr(err, "capacity") != NULL);
    siprotec_config_default(&c); c.base = 65520;
    CHECK(siprotec_new(&c, err, sizeof err) == NULL);
    siprotec_config_default(&c); c.seq_bits = 9;
    CHECK(siprotec_new(&c, err, sizeof err) == NULL);
    siprotec_config_default(&c); c.rate = -1;
    CHECK(siprotec_new(&c, err, sizeof err) == NULL);
}

static void t_hostile(void)
{
    siprotec_relay *r = mk(NULL);
    uint8_t resp[SIPROTEC_RESPONSE_MAX];
    /* malformed MBAP: closed */
    uint8_t bad_proto[] = { 0, 1, 0, 1, 0, 6, 1, 3, 2, 88, 0, 2 };
    CHECK_EQ(siprotec_handle(r, bad_proto, sizeof bad_proto, resp, sizeof resp), -1);
    uint8_t bad_len[] = { 0, 1, 0, 0, 0, 9, 1, 3, 2, 88, 0, 2 };
    CHECK_EQ(siprotec_handle(r, bad_len, sizeof bad_len, resp, sizeof resp), -1);
    CHECK_EQ(siprotec_handle(r, bad_len, 5, resp, sizeof resp), -1);
    /* wrong PDU lengths: exception 03 */
    CHECK_EQ(send_pdu(r, (uint8_t[]){ 3, 2, 88, 0 }, 4), 9);
    CHECK_EQ(g_resp[8], 3);
    CHECK_EQ(send_pdu(r, (uint8_t[]){ 16, 2, 89, 0, 1, 4, 0, 1, 0, 0 }, 10), 9);
    CHECK_EQ(g_resp[8], 3);
    CHECK_EQ(send_pdu(r, (uint8_t[]){ 6, 2, 89, 1 }, 4), 9);
    CHECK_EQ(g_resp[8], 3);
    CHECK_EQ(rd(r, 3, B, 0, NULL), 3);
    CHECK_EQ(rd(r, 3, B, 126, NULL), 3);
    /* random frames: a well-formed answer, never a crash */
    uint32_t x = 12345;
    uint8_t req[300];
    for (int i = 0; i < 200000; i++) {
        size_t plen = 1 + (x % 12);
        for (size_t k = 0; k < plen; k++) {
            x = x * 1103515245u + 12345u;
            req[7 + k] = (uint8_t)(x >> 16);
        }
        if (plen >= 3 && (x & 1)) { req[8] = 2; req[9] = (uint8_t)(88 + (x >> 8) % 28); } /* in the map */
        if (plen >= 1 && (x & 2)) req[7] = (uint8_t[]){ 3, 6, 16 }[(x >> 4) % 3];
        req[0] = 0; req[1] = 1; req[2] = 0; req[3] = 0; req[4] = 0; req[5] = (uint8_t)(plen + 1); req[6] = 9;
        long n = siprotec_handle(r, req, 7 + plen, resp, sizeof resp);
        if (n < 9 || n > SIPROTEC_RESPONSE_MAX || resp[6] != 9 || ((long)resp[4] << 8 | resp[5]) != n - 6) {
            CHECK(0);
            break;
        }
        if (i % 1000 == 0)
            script_n(r, 1, 2), siprotec_advance(r, (uint64_t)i * 1000000u);
    }
    siprotec_stats s;
    siprotec_get_stats(r, &s);
    CHECK(s.entries <= 200);
    siprotec_free(r);
}

int main(int argc, char **argv)
{
    run("relay_empty_map", t_empty_map);
    run("relay_handshake", t_handshake);
    run("relay_frozen_until_ack", t_frozen_until_ack);
    run("relay_partial_ack", t_partial_ack);
    run("relay_bad_acks", t_bad_acks);
    run("relay_bad_ack_ignored", t_bad_ack_ignored);
    run("relay_reset_list", t_reset_list);
    run("relay_overflow", t_overflow);
    run("relay_write_protect", t_write_protect);
    run("relay_base", t_base);
    run("relay_sources", t_sources);
    run("relay_seq_wrap", t_seq_wrap);
    run("relay_script_order", t_script_order);
    run("relay_bad_config", t_bad_config);
    run("relay_hostile", t_hostile);
    return unit_finish(argc, argv, "siprotec unit");
}
