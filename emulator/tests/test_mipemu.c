/* Unit tests of the mipemu core: register semantics through raw Modbus frames, and radio
 * statistics in virtual time (loss rate, slot timing, duplicates, determinism). */
#include "mipemu.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define UNIT_CLASS "emulator.unit"
#include "unit.h"
#include "pdu.h"

/* ---- request helpers ---- */

static uint8_t g_resp[MIPEMU_RESPONSE_MAX];
static long g_rlen;
static unsigned g_tid;

static long send_pdu(mipemu_net *n, int ep, unsigned unit, const uint8_t *pdu, size_t plen)
{
    uint8_t req[MIPEMU_FRAME_MAX];
    g_tid++;
    req[0] = (uint8_t)(g_tid >> 8); req[1] = (uint8_t)g_tid;
    req[2] = 0; req[3] = 0;
    req[4] = (uint8_t)((plen + 1) >> 8); req[5] = (uint8_t)(plen + 1);
    req[6] = (uint8_t)unit;
    memcpy(req + 7, pdu, plen);
    g_rlen = mipemu_handle(n, ep, req, plen + 7, g_resp, sizeof g_resp);
    return g_rlen;
}

/* returns the exception code, or 0 on success (values into vals) */
static int rd(mipemu_net *n, int ep, unsigned unit, unsigned fc, unsigned a, unsigned q, uint16_t *vals)
{
    uint8_t p[5] = { (uint8_t)fc, (uint8_t)(a >> 8), (uint8_t)a, (uint8_t)(q >> 8), (uint8_t)q };
    if (send_pdu(n, ep, unit, p, 5) < 9)
        return -1;
    return pdu_read_reply(g_resp, g_rlen, q, vals);
}

static int wr16(mipemu_net *n, int ep, unsigned unit, unsigned a, unsigned q, const uint16_t *vals)
{
    uint8_t p[6 + 2 * 130];
    if (send_pdu(n, ep, unit, p, pdu_write_regs(p, a, q, vals)) < 9)
        return -1;
    return g_resp[7] & 0x80 ? g_resp[8] : 0;
}

static int wr6(mipemu_net *n, int ep, unsigned unit, unsigned a, unsigned v)
{
    uint8_t p[5] = { 6, (uint8_t)(a >> 8), (uint8_t)a, (uint8_t)(v >> 8), (uint8_t)v };
    if (send_pdu(n, ep, unit, p, 5) < 9)
        return -1;
    return g_resp[7] & 0x80 ? g_resp[8] : 0;
}

static int fc23(mipemu_net *n, int ep, unsigned unit, unsigned ra, unsigned rq, unsigned wa, unsigned wq,
                const uint16_t *w, uint16_t *r)
{
    uint8_t p[10 + 2 * 130];
    p[0] = 23; p[1] = (uint8_t)(ra >> 8); p[2] = (uint8_t)ra; p[3] = (uint8_t)(rq >> 8); p[4] = (uint8_t)rq;
    p[5] = (uint8_t)(wa >> 8); p[6] = (uint8_t)wa; p[7] = (uint8_t)(wq >> 8); p[8] = (uint8_t)wq; p[9] = (uint8_t)(2 * wq);
    for (unsigned i = 0; i < wq; i++) { p[10 + 2 * i] = (uint8_t)(w[i] >> 8); p[11 + 2 * i] = (uint8_t)w[i]; }
    if (send_pdu(n, ep, unit, p, 10 + 2 * wq) < 9)
        return -1;
    if (g_resp[7] & 0x80)
        return g_resp[8];
    for (unsigned i = 0; r && i < rq; i++)
        r[i] = (uint16_t)(g_resp[9 + 2 * i] << 8 | g_resp[10 + 2 * i]);
    return 0;
}

static mipemu_net *mk(int stations, int mode, double ld, double lu, uint64_t seed)
{
    mipemu_config c;
    mipemu_config_default(&c);
    c.stations = stations;
    c.mode = mode;
    c.loss_down = ld;
    c.loss_up = lu;
    c.seed = seed;
    if (mode == MIPEMU_STATIC)
        c.static_registers = 10;
    char err[128];
    mipemu_net *n = mipemu_net_new(&c, err, sizeof err);
    if (!n) {
        fprintf(stderr, "net_new: %s\n", err);
        exit(2);
    }
    return n;
}

static uint16_t reg1(mipemu_net *n, int ep, unsigned unit, unsigned a)
{
    uint16_t v = 0xDEAD;
    rd(n, ep, unit, 3, a, 1, &v);
    return v;
}

/* ---- register semantics ---- */

static void t_trm_map(void)
{
    mipemu_net *n = mk(2, MIPEMU_DYNAMIC, 0, 0, 1);
    CHECK_EQ(rd(n, 1, 1, 3, 2000, 125, NULL), 0);
    CHECK_EQ(rd(n, 1, 1, 3, 2024, 125, NULL), 0);       /* 2024..2148 */
    CHECK_EQ(rd(n, 1, 1, 3, 2025, 125, NULL), 2);       /* 2149 is outside */
    CHECK_EQ(rd(n, 1, 1, 3, 1999, 1, NULL), 2);
    CHECK_EQ(rd(n, 1, 1, 3, 2197, 1, NULL), 2);
    CHECK_EQ(rd(n, 1, 1, 3, 2198, 125, NULL), 0);
    CHECK_EQ(rd(n, 1, 1, 3, 2223, 125, NULL), 0);       /* up to 2347 */
    CHECK_EQ(rd(n, 1, 1, 3, 2348, 1, NULL), 2);
    CHECK_EQ(rd(n, 1, 1, 3, 2198, 126, NULL), 3);       /* quantity checked before address */
    CHECK_EQ(rd(n, 1, 1, 3, 2198, 0, NULL), 3);
    CHECK_EQ(rd(n, 1, 1, 4, 2198, 2, NULL), 0);         /* FC4: same map */
    CHECK_EQ(rd(n, 2, 99, 3, 2000, 1, NULL), 0);        /* TRM: unit id is not checked */
    uint16_t v[1] = { 5 };
    CHECK_EQ(wr16(n, 1, 1, 2000, 1, v), 2);             /* read-only */
    CHECK_EQ(wr16(n, 1, 1, 2198, 1, v), 2);
    CHECK_EQ(wr16(n, 1, 1, 2200, 1, v), 2);
    mipemu_net_free(n);
}

static void t_mdp_map(void)
{
    mipemu_net *n = mk(3, MIPEMU_DYNAMIC, 0, 0, 1);
    CHECK_EQ(rd(n, 0, 1, 3, 0, 3, NULL), 0);
    CHECK_EQ(rd(n, 0, 1, 3, 3, 1, NULL), 2);
    CHECK_EQ(rd(n, 0, 1, 3, 4, 1, NULL), 0);
    for (unsigned a = 5; a <= 8; a++)
        CHECK_EQ(rd(n, 0, 1, 3, a, 1, NULL), 2);
    CHECK_EQ(rd(n, 0, 1, 3, 9, 125, NULL), 0);
    CHECK_EQ(rd(n, 0, 1, 3, 157, 1, NULL), 0);
    CHECK_EQ(rd(n, 0, 1, 3, 158, 1, NULL), 2);
    CHECK_EQ(rd(n, 0, 1, 3, 167, 1, NULL), 2);
    CHECK_EQ(rd(n, 0, 1, 3, 197, 1, NULL), 2);
    CHECK_EQ(rd(n, 0, 1, 3, 198, 125, NULL), 0);
    CHECK_EQ(rd(n, 0, 1, 3, 347, 1, NULL), 0);
    CHECK_EQ(rd(n, 0, 1, 3, 348, 1, NULL), 2);
    CHECK_EQ(rd(n, 0, 0, 3, 0, 1, NULL), 0x0B);
    CHECK_EQ(rd(n, 0, 4, 3, 0, 1, NULL), 0x0B);
    CHECK_EQ(rd(n, 0, 3, 3, 0, 1, NULL), 0);
    CHECK_EQ(wr6(n, 0, 1, 1, 7), 2);
    CHECK_EQ(wr6(n, 0, 1, 9, 7), 2);
    mipemu_net_free(n);
}

static void t_function_codes(void)
{
    mipemu_net *n = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    uint8_t p[5] = { 1, 0, 0, 0, 1 };
    for (unsigned fc = 1; fc < 128; fc++) {
        if (fc == 3 || fc == 4 || fc == 6 || fc == 16 || fc == 23)
            continue;
        p[0] = (uint8_t)fc;
        send_pdu(n, 0, 1, p, 5);
        CHECK_EQ(g_rlen, 9);
        CHECK_EQ(g_resp[7], fc | 0x80);
        CHECK_EQ(g_resp[8], 1);
    }
    /* response echoes transaction and unit id */
    uint8_t q[5] = { 3, 0, 2, 0, 1 };
    send_pdu(n, 0, 1, q, 5);
    CHECK_EQ(g_resp[0] << 8 | g_resp[1], g_tid);
    CHECK_EQ(g_resp[6], 1);
    CHECK_EQ(g_resp[4] << 8 | g_resp[5], 5);
    mipemu_net_free(n);
}

static void t_quantities(void)
{
    mipemu_net *n = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    uint16_t v[130] = { 0 };
    CHECK_EQ(wr16(n, 1, 1, 2001, 123, v), 0);
    CHECK_EQ(wr16(n, 1, 1, 2001, 124, v), 3);
    CHECK_EQ(wr16(n, 1, 1, 2001, 127, v), 3);
    CHECK_EQ(fc23(n, 1, 1, 2198, 125, 2001, 121, v, NULL), 0);
    CHECK_EQ(fc23(n, 1, 1, 2198, 125, 2001, 122, v, NULL), 3);
    CHECK_EQ(fc23(n, 1, 1, 2198, 126, 2001, 121, v, NULL), 3);
    mipemu_net_free(n);

    mipemu_config c;
    mipemu_config_default(&c);
    c.allow_127 = 1;
    n = mipemu_net_new(&c, NULL, 0);
    CHECK_EQ(wr16(n, 1, 1, 2001, 127, v), 0);
    CHECK_EQ(reg1(n, 1, 1, 2000), 127);
    CHECK_EQ(wr16(n, 1, 1, 2001, 128, v), 3);
    CHECK_EQ(rd(n, 1, 1, 3, 2198, 127, NULL), 0);
    CHECK_EQ(rd(n, 1, 1, 3, 2198, 128, NULL), 3);
    CHECK_EQ(fc23(n, 1, 1, 2198, 127, 2001, 127, v, NULL), 0);
    mipemu_net_free(n);
}

static void t_malformed(void)
{
    mipemu_net *n = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    uint8_t f[16] = { 0, 1, 0, 0, 0, 6, 1, 3, 0, 2, 0, 1 };
    uint8_t out[MIPEMU_RESPONSE_MAX];
    CHECK_EQ(mipemu_frame_length(f, 6), 0);
    CHECK_EQ(mipemu_frame_length(f, 7), 12);
    CHECK(mipemu_handle(n, 0, f, 12, out, sizeof out) > 0);
    f[2] = 1; /* protocol id */
    CHECK_EQ(mipemu_frame_length(f, 12), -1);
    CHECK_EQ(mipemu_handle(n, 0, f, 12, out, sizeof out), -1);
    f[2] = 0; f[5] = 1; /* length 1: no function code */
    CHECK_EQ(mipemu_frame_length(f, 12), -1);
    f[4] = 0x04; f[5] = 0x01; /* 1025 > max */
    CHECK_EQ(mipemu_frame_length(f, 12), -1);
    f[4] = 0; f[5] = 7; /* length says 13 bytes, only 12 given */
    CHECK_EQ(mipemu_handle(n, 0, f, 12, out, sizeof out), -1);
    f[5] = 6;
    CHECK_EQ(mipemu_handle(n, 5, f, 12, out, sizeof out), -1); /* no such endpoint */
    /* a PDU too short for its function code: exception 03, not a close */
    uint8_t p[3] = { 3, 0, 2 };
    send_pdu(n, 0, 1, p, 3);
    CHECK_EQ(g_rlen, 9);
    CHECK_EQ(g_resp[8], 3);
    uint8_t w[8] = { 16, 0x07, 0xD1, 0, 2, 4, 0, 1 }; /* byte count says 4, 2 present */
    send_pdu(n, 1, 1, w, 8);
    CHECK_EQ(g_resp[8], 3);
    mipemu_net_free(n);
}

static void t_dynamic_write(void)
{
    mipemu_net *n = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    uint16_t v[5] = { 1, 2, 3, 4, 5 };
    CHECK_EQ(wr16(n, 1, 1, 2002, 2, v), 2);   /* must start at the first write register */
    CHECK_EQ(wr6(n, 1, 1, 2001, 9), 2);       /* single writes are not blocks */
    CHECK_EQ(reg1(n, 1, 1, 2000), 0);
    CHECK_EQ(reg1(n, 1, 1, 2198), 0);
    CHECK_EQ(wr16(n, 1, 1, 2001, 5, v), 0);
    CHECK_EQ(reg1(n, 1, 1, 2000), 5);
    CHECK_EQ(reg1(n, 1, 1, 2198), MIPEMU_RS_WRITE_WAITING | MIPEMU_RS_WRITE_UNCONFIRMED);
    CHECK_EQ(wr16(n, 1, 1, 2001, 3, v + 2), 0); /* replaces before it was sent */
    CHECK_EQ(reg1(n, 1, 1, 2000), 3);
    CHECK_EQ(fc23(n, 1, 1, 2000, 4, 2001, 2, v, NULL), 0);
    CHECK_EQ(reg1(n, 1, 1, 2000), 2);
    CHECK_EQ(fc23(n, 1, 1, 2000, 4, 2003, 2, v, NULL), 2);
    CHECK_EQ(reg1(n, 1, 1, 2000), 2); /* the rejected FC23 changed nothing */
    /* MDP side, station 1 */
    CHECK_EQ(wr16(n, 0, 1, 10, 4, v), 0);
    CHECK_EQ(reg1(n, 0, 1, 9), 4);
    CHECK_EQ(reg1(n, 0, 1, 2), 0x12);
    CHECK_EQ(wr16(n, 0, 1, 11, 4, v), 2);
    mipemu_net_free(n);
}

/* advance by whole slots until the condition on the register holds, at most limit ns */
static int wait_reg(mipemu_net *n, int ep, unsigned unit, unsigned a, uint16_t mask, uint16_t want, uint64_t limit)
{
    uint64_t end = mipemu_net_now(n) + limit;
    while (mipemu_net_now(n) < end) {
        mipemu_net_advance(n, mipemu_net_next_event(n));
        if ((reg1(n, ep, unit, a) & mask) == want)
            return 1;
    }
    return 0;
}

static void t_uplink_and_new_data(void)
{
    mipemu_net *n = mk(2, MIPEMU_DYNAMIC, 0, 0, 1);
    uint16_t v[4] = { 7, 100, 200, 300 };
    CHECK_EQ(wr16(n, 2, 1, 2001, 4, v), 0);
    CHECK(wait_reg(n, 0, 2, 2, 1, 1, 5000000000ULL));
    CHECK_EQ(reg1(n, 0, 2, 4), 4);
    CHECK_EQ(reg1(n, 0, 2, 199), 4);
    CHECK_EQ(reg1(n, 0, 1, 2), 0);          /* station 1 got nothing */
    /* reading status and count alone clears nothing */
    uint16_t r[6];
    CHECK_EQ(rd(n, 0, 2, 3, 198, 2, r), 0);
    CHECK_EQ(r[0] & 1, 1);
    CHECK_EQ(rd(n, 0, 2, 3, 198, 2, r), 0);
    CHECK_EQ(r[0] & 1, 1);
    /* a read touching the read area: response still shows the bit, then it is clear */
    CHECK_EQ(rd(n, 0, 2, 3, 198, 6, r), 0);
    CHECK_EQ(r[0] & 1, 1);
    CHECK_EQ(r[2], 7);
    CHECK_EQ(r[5], 300);
    CHECK_EQ(reg1(n, 0, 2, 2) & 1, 0);
    CHECK_EQ(reg1(n, 0, 2, 198) & 1, 0);
    /* the sender: waiting and unconfirmed cleared, count back to 0 once confirmed */
    CHECK(wait_reg(n, 2, 1, 2198, 0x12, 0, 5000000000ULL));
    CHECK_EQ(reg1(n, 2, 1, 2000), 0);
    /* overwrite of unread data: two blocks, the second replaces the first */
    CHECK_EQ(wr16(n, 2, 1, 2001, 2, v), 0);
    CHECK(wait_reg(n, 2, 1, 2198, 0x10, 0, 5000000000ULL));
    uint16_t w[3] = { 8, 9, 10 };
    CHECK_EQ(wr16(n, 2, 1, 2001, 3, w), 0);
    CHECK(wait_reg(n, 2, 1, 2198, 0x10, 0, 5000000000ULL));
    CHECK_EQ(rd(n, 0, 2, 3, 198, 5, r), 0);
    CHECK_EQ(r[0] & 1, 1);
    CHECK_EQ(r[1], 3);
    CHECK_EQ(r[2], 8);
    CHECK_EQ(r[4], 10);
    /* FC4 read of the read area clears too; FC23 read part as well */
    CHECK_EQ(wr16(n, 0, 2, 10, 1, w), 0);
    CHECK(wait_reg(n, 2, 1, 2198, 1, 1, 5000000000ULL));
    CHECK_EQ(rd(n, 2, 1, 4, 2200, 1, r), 0);
    CHECK_EQ(r[0], 8);
    CHECK_EQ(reg1(n, 2, 1, 2198) & 1, 0);
    CHECK_EQ(wr16(n, 0, 2, 10, 1, w + 1), 0);
    CHECK(wait_reg(n, 2, 1, 2198, 1, 1, 5000000000ULL));
    CHECK_EQ(fc23(n, 2, 1, 2198, 3, 2001, 1, w, r), 0);
    CHECK_EQ(r[0] & 1, 1);
    CHECK_EQ(r[2], 9);
    CHECK_EQ(reg1(n, 2, 1, 2198) & 1, 0);
    mipemu_net_free(n);
}

static void t_static_mode(void)
{
    mipemu_net *n = mk(1, MIPEMU_STATIC, 0, 0, 1);
    CHECK_EQ(reg1(n, 1, 1, 2000), 10);
    CHECK_EQ(reg1(n, 0, 1, 9), 10);
    CHECK_EQ(wr6(n, 1, 1, 2005, 0), 0);     /* no change: nothing to send */
    CHECK_EQ(reg1(n, 1, 1, 2198), 0);
    CHECK_EQ(wr6(n, 1, 1, 2005, 55), 0);    /* anywhere in the area */
    CHECK_EQ(reg1(n, 1, 1, 2198), 0x12);
    CHECK(wait_reg(n, 1, 1, 2198, 0x12, 0, 5000000000ULL));
    CHECK_EQ(reg1(n, 1, 1, 2000), 10);      /* static: the count stays N */
    uint16_t r[12];
    CHECK_EQ(rd(n, 0, 1, 3, 198, 12, r), 0);
    CHECK_EQ(r[0] & 1, 1);
    CHECK_EQ(r[1], 10);
    CHECK_EQ(r[2 + 4], 55);
    /* beyond N: stored, not a change that is sent */
    CHECK_EQ(wr6(n, 1, 1, 2100, 1), 0);
    CHECK_EQ(reg1(n, 1, 1, 2198), 0);
    CHECK_EQ(reg1(n, 1, 1, 2100), 1);
    uint16_t v[3] = { 1, 2, 3 };
    CHECK_EQ(wr16(n, 0, 1, 12, 3, v), 0);   /* FC16 need not start at the first register */
    CHECK_EQ(reg1(n, 0, 1, 2), 0x12);
    mipemu_net_free(n);
}

/* ---- radio ---- */

typedef struct { char *buf; size_t len, cap; } sink_t;

static void sink_fn(void *user, const char *line, size_t len)
{
    sink_t *s = user;
    if (s->len + len + 1 > s->cap) {
        s->cap = (s->len + len) * 2 + 4096;
        s->buf = realloc(s->buf, s->cap);
    }
    memcpy(s->buf + s->len, line, len);
    s->len += len;
    s->buf[s->len] = 0; /* the tests search it as a string */
}

static int line_has(const char *p, const char *needle);

static void t_loss_rates(void)
{
    const double ps[] = { 0.0, 0.05, 0.2, 0.5 };
    for (size_t i = 0; i < sizeof ps / sizeof ps[0]; i++) {
        mipemu_net *n = mk(4, MIPEMU_DYNAMIC, ps[i], ps[i] / 2, 42 + i);
        uint64_t t = 0;
        mipemu_stats tot = { 0 };
        while (tot.tel_down < 20000 || tot.tel_up < 10000) {
            t += 1000000000ULL;
            mipemu_net_advance(n, t);
            memset(&tot, 0, sizeof tot);
            for (int s = 1; s <= 4; s++) {
                mipemu_stats st;
                mipemu_net_stats(n, s, &st);
                tot.tel_down += st.tel_down; tot.lost_down += st.lost_down;
                tot.tel_up += st.tel_up; tot.lost_up += st.lost_up;
            }
        }
        double od = (double)tot.lost_down / (double)tot.tel_down;
        double ou = (double)tot.lost_up / (double)tot.tel_up;
        /* 5 standard deviations of a binomial estimate, at least 0.005 */
        double tol_d = fmax(0.005, 5 * sqrt(ps[i] * (1 - ps[i]) / (double)tot.tel_down));
        double tol_u = fmax(0.005, 5 * sqrt(ps[i] / 2 * (1 - ps[i] / 2) / (double)tot.tel_up));
        printf("     loss down %.3f observed %.4f over %" PRIu64 ", up %.3f observed %.4f over %" PRIu64 "\n",
               ps[i], od, tot.tel_down, ps[i] / 2, ou, tot.tel_up);
        CHECK(fabs(od - ps[i]) <= tol_d);
        CHECK(fabs(ou - ps[i] / 2) <= tol_u);
        mipemu_net_free(n);
    }
}

static void t_burst_loss(void)
{
    mipemu_config c;
    mipemu_config_default(&c);
    c.stations = 2;
    c.loss_down = 0.1;
    c.loss_up = 0.1;
    c.burst = 8;
    c.seed = 7;
    mipemu_net *n = mipemu_net_new(&c, NULL, 0);
    sink_t s = { 0 };
    mipemu_net_set_trace(n, sink_fn, &s);
    mipemu_net_advance(n, 3600ULL * 1000000000ULL);
    mipemu_stats a, b;
    mipemu_net_stats(n, 1, &a);
    mipemu_net_stats(n, 2, &b);
    double up = (double)(a.lost_up + b.lost_up) / (double)(a.tel_up + b.tel_up);
    /* mean run length of lost uplink telegrams of station 1 */
    uint64_t runs = 0, lost = 0;
    int prev = 0;
    char line[600];
    for (char *p = s.buf; p && p < s.buf + s.len;) {
        char *e = memchr(p, '\n', (size_t)(s.buf + s.len - p));
        size_t ll = (size_t)(e - p) < sizeof line - 1 ? (size_t)(e - p) : sizeof line - 1;
        memcpy(line, p, ll);
        line[ll] = 0;
        if (strstr(line, "\"dir\":\"up\"") && strstr(line, "\"st\":1,")) {
            int l = strstr(line, "\"lost\":true") != NULL;
            if (l) { lost++; if (!prev) runs++; }
            prev = l;
        }
        p = e + 1;
    }
    double mean_run = runs ? (double)lost / (double)runs : 0;
    printf("     burst: uplink loss %.4f over %" PRIu64 " telegrams, mean burst %.2f (configured 8)\n", up,
           a.tel_up + b.tel_up, mean_run);
    CHECK(a.tel_up + b.tel_up >= 10000);
    CHECK(fabs(up - 0.1) < 0.03);
    CHECK(mean_run > 5 && mean_run < 11);
    free(s.buf);
    mipemu_net_free(n);
}

/* parse an unsigned field "key":123 from a trace line */
static uint64_t field(const char *line, const char *key)
{
    char k[32];
    snprintf(k, sizeof k, "\"%s\":", key);
    const char *p = strstr(line, k);
    return p ? strtoull(p + strlen(k), NULL, 10) : (uint64_t)-1;
}

/* whether the line that p points into contains needle (before its newline) */
static int line_has(const char *p, const char *needle)
{
    const char *e = strchr(p, '\n');
    const char *f = strstr(p, needle);
    return f && (!e || f < e);
}

static void t_slot_timing(void)
{
    mipemu_config c;
    mipemu_config_default(&c);
    c.stations = 1;
    c.bitrate = 4800;
    c.slot_gap_ns = 7000000;
    c.overhead_bytes = 10;
    mipemu_net *n = mipemu_net_new(&c, NULL, 0);
    sink_t s = { 0 };
    mipemu_net_set_trace(n, sink_fn, &s);
    uint16_t v[100] = { 0 };
    CHECK_EQ(wr16(n, 0, 1, 10, 100, v), 0);  /* MDP -> station: 100 registers */
    CHECK_EQ(wr16(n, 1, 1, 2001, 40, v), 0); /* station -> MDP: 40 registers */
    mipemu_net_advance(n, 2000000000ULL);
    /* slot 1: poll(100) gap answer(40) gap ack gap; then empty polls */
    uint64_t t_poll = (10 + 200) * 8ULL * 1000000000ULL / 4800;
    uint64_t t_ans = (10 + 80) * 8ULL * 1000000000ULL / 4800;
    uint64_t t_ack = 10 * 8ULL * 1000000000ULL / 4800;
    uint64_t g = 7000000;
    CHECK_EQ(mipemu_telegram_ns(&c, 100), t_poll);
    /* the radio lines in order */
    uint64_t T0[8], T[8], B[8];
    char K[8];
    int nl = 0;
    for (char *p = s.buf; p && nl < 8; p = strchr(p, '\n'), p = p ? p + 1 : NULL) {
        if (!line_has(p, "\"ev\":\"radio\""))
            continue;
        K[nl] = line_has(p, "\"poll\"") ? 'P' : line_has(p, "\"answer\"") ? 'A' : 'K';
        T0[nl] = field(p, "t0");
        T[nl] = field(p, "t");
        B[nl] = field(p, "bytes");
        nl++;
    }
    CHECK_EQ(nl, 8);
    /* slot 1 began at 0 before the writes: empty poll, the station answers with its 40 registers,
     * the MDP acknowledges. Slot 2: the 100-register poll, an empty answer. */
    char want[] = "PAKPAPAP";
    for (int i = 0; i < 8; i++)
        CHECK_EQ(K[i], want[i]);
    CHECK_EQ(T0[0], 0);
    CHECK_EQ(T[0], t_ack);
    CHECK_EQ(T0[1], T[0] + g);
    CHECK_EQ(T[1], T0[1] + t_ans);
    CHECK_EQ(B[1], 90);
    CHECK_EQ(T0[2], T[1] + g);
    CHECK_EQ(T[2], T0[2] + t_ack);
    CHECK_EQ(B[2], 10);
    CHECK_EQ(T0[3], T[2] + g);
    CHECK_EQ(T[3], T0[3] + t_poll);
    CHECK_EQ(B[3], 210);
    CHECK_EQ(T0[4], T[3] + g);
    CHECK_EQ(T[4], T0[4] + t_ack);
    CHECK_EQ(T0[5], T[4] + g);
    CHECK_EQ(T[5] - T0[5], t_ack);
    CHECK_EQ(T0[5], 2 * t_ack + t_ans + 3 * g + t_poll + t_ack + 2 * g);
    free(s.buf);
    mipemu_net_free(n);
}

/* collects the radio lines of a trace as (kind, station, t0, t, regs, lost) */
typedef struct { char kind; int st; uint64_t t0, t; int regs, lost, r0; } tel_t;

static int radio_lines(const sink_t *s, tel_t *out, int max)
{
    int n = 0;
    for (const char *p = s->buf; p && p < s->buf + s->len && n < max; p = strchr(p, '\n'), p = p ? p + 1 : NULL) {
        if (!line_has(p, "\"ev\":\"radio\""))
            continue;
        tel_t *x = &out[n++];
        x->kind = line_has(p, "\"poll\"") ? 'P' : line_has(p, "\"answer\"") ? 'A' : 'K';
        x->st = (int)field(p, "st");
        x->t0 = field(p, "t0");
        x->t = field(p, "t");
        x->regs = (int)field(p, "regs");
        x->r0 = line_has(p, "\"r0\"") ? (int)field(p, "r0") : -1;
        x->lost = line_has(p, "\"lost\":true");
    }
    return n;
}

static void t_lost_poll_timing(void)
{
    /* a lost poll: the MDP waits as long as an empty answer would take, then polls the next */
    mipemu_config c;
    mipemu_config_default(&c);
    c.stations = 2;
    c.loss_down = 1.0;
    mipemu_net *n = mipemu_net_new(&c, NULL, 0);
    sink_t s = { 0 };
    mipemu_net_set_trace(n, sink_fn, &s);
    mipemu_net_advance(n, 1000000000ULL);
    tel_t x[8];
    int k = radio_lines(&s, x, 8);
    uint64_t t0 = mipemu_telegram_ns(&c, 0), g = c.slot_gap_ns;
    CHECK_EQ(k, 8);
    for (int i = 0; i < k; i++) {
        CHECK_EQ(x[i].kind, 'P');                       /* never an answer */
        CHECK_EQ(x[i].st, 1 + i % 2);
        CHECK(x[i].lost);
        CHECK_EQ(x[i].t0, (uint64_t)i * (t0 + g + t0 + g));
        CHECK_EQ(x[i].t - x[i].t0, t0);
    }
    free(s.buf);
    mipemu_net_free(n);
}

static void t_replace_before_and_after_send(void)
{
    mipemu_net *n = mk(2, MIPEMU_DYNAMIC, 0, 0, 1);
    sink_t s = { 0 };
    mipemu_net_set_trace(n, sink_fn, &s);
    uint16_t a[4] = { 1, 11, 12, 13 }, b[2] = { 2, 21 }, c3[3] = { 3, 31, 32 };
    /* station 2 is polled after station 1's slot: two writes now, only the second goes on air */
    CHECK_EQ(wr16(n, 0, 2, 10, 4, a), 0);
    CHECK_EQ(wr16(n, 0, 2, 10, 2, b), 0);
    CHECK(wait_reg(n, 0, 2, 2, 0x10, 0, 5000000000ULL));
    tel_t x[64];
    int k = radio_lines(&s, x, 64);
    int seen = 0;
    for (int i = 0; i < k; i++)
        if (x[i].kind == 'P' && x[i].regs > 0) {
            CHECK_EQ(x[i].regs, 2);
            CHECK_EQ(x[i].r0, 2);
            seen++;
        }
    CHECK_EQ(seen, 1);
    CHECK_EQ(reg1(n, 2, 1, 2199), 2);
    mipemu_net_free(n);
    free(s.buf);

    /* sent but unconfirmed (answer lost), then a new write: the new block replaces the repeat */
    mipemu_config cf;
    mipemu_config_default(&cf);
    cf.loss_up = 1.0;          /* no answer ever arrives: nothing is confirmed */
    n = mipemu_net_new(&cf, NULL, 0);
    s.buf = NULL; s.len = s.cap = 0;
    mipemu_net_set_trace(n, sink_fn, &s);
    mipemu_net_advance(n, mipemu_net_next_event(n));   /* past the first (empty) slot start */
    CHECK_EQ(wr16(n, 0, 1, 10, 4, a), 0);
    CHECK(wait_reg(n, 0, 1, 2, 0x12, 0x10, 5000000000ULL)); /* sent, unconfirmed */
    CHECK_EQ(reg1(n, 0, 1, 1) & MIPEMU_ST_DOWN_RESEND, 0);
    mipemu_net_advance(n, mipemu_net_now(n) + 200000000ULL); /* repeated meanwhile */
    CHECK_EQ(reg1(n, 0, 1, 1) & MIPEMU_ST_DOWN_RESEND, MIPEMU_ST_DOWN_RESEND);
    CHECK_EQ(wr16(n, 0, 1, 10, 3, c3), 0);
    CHECK_EQ(reg1(n, 0, 1, 2), 0x12);
    CHECK_EQ(reg1(n, 0, 1, 9), 3);
    mipemu_net_advance(n, mipemu_net_now(n) + 1000000000ULL);
    k = radio_lines(&s, x, 64);
    int last_a = -1, first_c = -1;
    for (int i = 0; i < k; i++) {
        if (x[i].kind != 'P' || x[i].regs == 0)
            continue;
        if (x[i].r0 == 1) last_a = i;
        if (x[i].r0 == 3 && first_c < 0) first_c = i;
    }
    CHECK(last_a >= 0 && first_c > last_a);
    for (int i = first_c; i >= 0 && i < k; i++)   /* once replaced, the old block never returns */
        if (x[i].kind == 'P')
            CHECK_EQ(x[i].r0, 3);
    CHECK_EQ(reg1(n, 0, 1, 2), 0x10);
    mipemu_net_free(n);
    free(s.buf);
}

static void t_duplicates(void)
{
    /* uplink lossy only: a lost answer means the downlink block was delivered but unconfirmed,
     * so it is sent again and the station sees it twice */
    mipemu_net *n = mk(1, MIPEMU_DYNAMIC, 0.0, 0.5, 3);
    uint64_t dups = 0, blocks = 0;
    uint16_t v[3] = { 1, 2, 3 };
    for (int i = 0; i < 200; i++) {
        v[0] = (uint16_t)i;
        CHECK_EQ(wr16(n, 0, 1, 10, 3, v), 0);
        CHECK(wait_reg(n, 0, 1, 2, 0x10, 0, 60000000000ULL));
    }
    mipemu_stats st;
    mipemu_net_stats(n, 1, &st);
    dups = st.dup_down;
    blocks = st.blocks_down;
    printf("     down blocks delivered %" PRIu64 ", of them duplicates %" PRIu64 ", confirmed %" PRIu64 "\n",
           blocks, dups, st.confirmed_down);
    CHECK(dups > 50);
    CHECK_EQ(blocks - dups, 200);       /* every block arrived, none lost */
    CHECK_EQ(st.confirmed_down, 200);
    mipemu_net_free(n);

    /* downlink ack lost: the uplink block is repeated at the next poll, duplicate at the MDP */
    n = mk(1, MIPEMU_DYNAMIC, 0.3, 0.0, 4);
    for (int i = 0; i < 200; i++) {
        v[0] = (uint16_t)i;
        CHECK_EQ(wr16(n, 1, 1, 2001, 3, v), 0);
        CHECK(wait_reg(n, 1, 1, 2198, 0x10, 0, 60000000000ULL));
    }
    mipemu_net_stats(n, 1, &st);
    printf("     up blocks delivered %" PRIu64 ", of them duplicates %" PRIu64 "\n", st.blocks_up, st.dup_up);
    CHECK(st.dup_up > 20);
    CHECK_EQ(st.blocks_up - st.dup_up, 200);
    mipemu_net_free(n);
}

static void t_unreachable(void)
{
    mipemu_net *n = mk(2, MIPEMU_DYNAMIC, 1.0, 0.0, 5);
    CHECK_EQ(reg1(n, 0, 1, 1), 0);
    mipemu_net_advance(n, 10000000000ULL);
    CHECK_EQ(reg1(n, 0, 1, 1), MIPEMU_ST_UNREACHABLE);
    CHECK_EQ(reg1(n, 0, 2, 1), MIPEMU_ST_UNREACHABLE);
    CHECK_EQ(reg1(n, 0, 1, 0), 0);   /* never heard: no field strength */
    mipemu_net_free(n);
    /* polls arrive, answers never: the station's report of its level never reaches the MDP */
    n = mk(1, MIPEMU_DYNAMIC, 0.0, 1.0, 5);
    mipemu_net_advance(n, 10000000000ULL);
    CHECK_EQ(reg1(n, 0, 1, 1), MIPEMU_ST_UNREACHABLE);
    CHECK_EQ(reg1(n, 0, 1, 0), 0);
    mipemu_net_free(n);
    /* long outages: unreachable, then reachable again, each traced once per change */
    mipemu_config c;
    mipemu_config_default(&c);
    c.loss_down = 0.5;
    c.burst = 40;
    c.seed = 11;
    n = mipemu_net_new(&c, NULL, 0);
    sink_t tr = { 0 };
    mipemu_net_set_trace(n, sink_fn, &tr);
    int saw_unreach = 0, saw_back = 0;
    for (int i = 0; i < 3000; i++) {
        mipemu_net_advance(n, mipemu_net_next_event(n));
        uint16_t v = reg1(n, 0, 1, 1);
        if (v & MIPEMU_ST_UNREACHABLE) {
            saw_unreach = 1;
            CHECK_EQ(v & MIPEMU_ST_ANSWERED, 0);
        } else if (saw_unreach && (v & MIPEMU_ST_ANSWERED)) {
            saw_back = 1;
        }
    }
    CHECK(saw_unreach && saw_back);
    int downs = 0, ups = 0;
    for (char *p = tr.buf; (p = strstr(p, "\"ev\":\"station\"")) != NULL; p++) {
        downs += line_has(p, "\"unreachable\"");
        ups += line_has(p, "\"reachable\"") && !line_has(p, "\"unreachable\"");
    }
    CHECK(downs > 0);
    CHECK(ups == downs || ups == downs - 1);   /* strictly alternating */
    free(tr.buf);
    mipemu_net_free(n);
    n = mk(2, MIPEMU_DYNAMIC, 0.0, 0.0, 5);
    mipemu_net_advance(n, 10000000000ULL);
    uint16_t st = reg1(n, 0, 1, 1);
    CHECK_EQ(st, MIPEMU_ST_ANSWERED | MIPEMU_ST_EVER_ANSWERED);
    uint16_t fs = reg1(n, 0, 1, 0);
    CHECK((fs >> 8) >= 50 && (fs >> 8) <= 110);
    CHECK((fs & 0xFF) >= 45 && (fs & 0xFF) <= 110);
    /* noise: over many polls the value changes */
    int changed = 0;
    for (int i = 0; i < 20; i++) {
        mipemu_net_advance(n, mipemu_net_now(n) + 1000000000ULL);
        changed |= reg1(n, 0, 1, 0) != fs;
    }
    CHECK(changed);
    mipemu_net_free(n);
}

static void run_scripted(uint64_t seed, sink_t *s)
{
    mipemu_config c;
    mipemu_config_default(&c);
    c.stations = 3;
    c.loss_down = 0.2;
    c.loss_up = 0.1;
    c.burst = 3;
    c.seed = seed;
    mipemu_net *n = mipemu_net_new(&c, NULL, 0);
    mipemu_net_set_trace(n, sink_fn, s);
    g_tid = 0;
    uint16_t v[20];
    for (int i = 0; i < 300; i++) {
        for (int k = 0; k < 20; k++) v[k] = (uint16_t)(i * k);
        mipemu_net_advance(n, (uint64_t)i * 250000000ULL);
        wr16(n, 1 + i % 3, 1, 2001, 1 + (unsigned)i % 20, v);
        wr16(n, 0, 1 + (unsigned)(i + 1) % 3, 10, 1 + (unsigned)i % 7, v);
        rd(n, 0, 1 + (unsigned)i % 3, 3, 198, 30, NULL);
    }
    mipemu_net_free(n);
}

static void t_determinism(void)
{
    sink_t a = { 0 }, b = { 0 }, c = { 0 };
    run_scripted(99, &a);
    run_scripted(99, &b);
    run_scripted(100, &c);
    CHECK(a.len > 10000);
    CHECK_EQ(a.len, b.len);
    CHECK(a.len == b.len && memcmp(a.buf, b.buf, a.len) == 0);
    CHECK(a.len != c.len || memcmp(a.buf, c.buf, a.len) != 0);
    /* a hash of the trace, so a change across machines or compilers shows */
    uint64_t h = 1469598103934665603ULL;
    for (size_t i = 0; i < a.len; i++) h = (h ^ (uint8_t)a.buf[i]) * 1099511628211ULL;
    printf("     trace %zu bytes, fnv1a %016" PRIx64 "\n", a.len, h);
    free(a.buf); free(b.buf); free(c.buf);
}

static void t_two_networks(void)
{
    /* no shared state: two networks in one process do not see each other */
    mipemu_net *a = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    mipemu_net *b = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    uint16_t v[1] = { 77 };
    CHECK_EQ(wr16(a, 1, 1, 2001, 1, v), 0);
    mipemu_net_advance(a, 2000000000ULL);
    mipemu_net_advance(b, 2000000000ULL);
    CHECK_EQ(reg1(a, 0, 1, 200), 77);
    CHECK_EQ(reg1(b, 0, 1, 200), 0);
    CHECK_EQ(reg1(b, 0, 1, 2), 0);
    CHECK_EQ(mipemu_net_advance(a, 1000), -1); /* time does not go back */
    mipemu_net_free(a);
    mipemu_net_free(b);
}

static void t_bad_config(void)
{
    mipemu_config c;
    char err[128];
    mipemu_config_default(&c);
    c.stations = 0;
    CHECK(mipemu_net_new(&c, err, sizeof err) == NULL);
    CHECK(strstr(err, "stations") != NULL);
    mipemu_config_default(&c);
    c.loss_up = 1.5;
    CHECK(mipemu_net_new(&c, err, sizeof err) == NULL);
    mipemu_config_default(&c);
    c.static_registers = 149;
    CHECK(mipemu_net_new(&c, err, sizeof err) == NULL);
    mipemu_config_default(&c);
    c.bitrate = 0;
    CHECK(mipemu_net_new(&c, err, sizeof err) == NULL);
}

/* The scripted fault of the note's example: record 2 is lost once, then delivered on the link's
 * resend; record 1 and every later record 2 pass untouched. */
static void t_lose_record(void)
{
    mipemu_config c;
    mipemu_config_default(&c);
    c.lose_record = 2;
    char err[128];
    mipemu_net *n = mipemu_net_new(&c, err, sizeof err);
    CHECK(n != NULL);
    sink_t s = { 0 };
    mipemu_net_set_trace(n, sink_fn, &s);
    for (uint16_t rec = 1; rec <= 3; rec++) {
        uint16_t v[2] = { rec, (uint16_t)(100 + rec) };
        CHECK_EQ(wr16(n, 1, 1, 2001, 2, v), 0);
        CHECK(wait_reg(n, 1, 1, 2198, 0x10, 0, 5000000000ULL)); /* confirmed */
        uint16_t r[4];
        CHECK_EQ(rd(n, 0, 1, 3, 198, 4, r), 0);
        CHECK_EQ(r[2], rec);
    }
    mipemu_stats st;
    CHECK_EQ(mipemu_net_stats(n, 1, &st), 0);
    CHECK_EQ(st.lost_up, 1);
    CHECK_EQ(st.blocks_up, 3);
    CHECK(s.buf && strstr(s.buf, "\"r0\":2,\"lost\":true") != NULL);  /* the trace shows it */
    free(s.buf);
    mipemu_net_free(n);
    c.lose_record = 70000;
    CHECK(mipemu_net_new(&c, err, sizeof err) == NULL);
}

/* ---- scripted fates (mipemu_net_set_fate) ---- */

/* The fates the hook returns, in call order per direction (then OK), and what it was given. */
typedef struct {
    int down[4], up[4];
    int calls_down, calls_up;
    int station;
    uint16_t r0_down[8], r0_up[8];
    int len_up;
} script_t;

static int script_fn(void *user, int station, int up, const uint16_t *blk, int len)
{
    script_t *sc = user;
    sc->station = station;
    int *k = up ? &sc->calls_up : &sc->calls_down;
    uint16_t *r0 = up ? sc->r0_up : sc->r0_down;
    if (*k < 8)
        r0[*k] = len > 0 ? blk[0] : 0xFFFF;
    if (up)
        sc->len_up = len;
    int f = *k < 4 ? (up ? sc->up[*k] : sc->down[*k]) : MIPEMU_FATE_OK;
    (*k)++;
    return f;
}

static mipemu_net *mk_scripted(script_t *sc, sink_t *tr)
{
    mipemu_net *n = mk(1, MIPEMU_DYNAMIC, 0, 0, 1);
    mipemu_net_set_fate(n, script_fn, sc);
    mipemu_net_set_trace(n, sink_fn, tr);
    return n;
}

/* Runs until k more slots have started. A slot takes the MDP's block when it starts, the
 * station's when its poll arrives: after slots() a block written at the MDP goes in the next
 * slot, one written at the station in the slot that has just started. */
static void slots(mipemu_net *n, int k)
{
    mipemu_stats st;
    mipemu_net_stats(n, 1, &st);
    uint64_t want = st.polls + (uint64_t)k;
    while (st.polls < want) {
        mipemu_net_advance(n, mipemu_net_next_event(n));
        mipemu_net_stats(n, 1, &st);
    }
}

/* an MDP block d and a station block u in the same slot (the second one); returns with that slot
 * started */
static void both_in_next_slot(mipemu_net *n, const uint16_t *d, unsigned dn, const uint16_t *u, unsigned un)
{
    if (dn)
        CHECK_EQ(wr16(n, 0, 1, 10, dn, d), 0);
    slots(n, 1);
    if (un)
        CHECK_EQ(wr16(n, 1, 1, 2001, un, u), 0);
}

static void t_fate_lost(void)
{
    /* a lost poll: not delivered, no answer in that slot (the station's block waits), sent again */
    script_t sc = { .down = { MIPEMU_FATE_LOST } };
    sink_t tr = { 0 };
    mipemu_net *n = mk_scripted(&sc, &tr);
    uint16_t d[2] = { 5, 55 }, u[2] = { 6, 66 };
    both_in_next_slot(n, d, 2, u, 2);
    mipemu_stats st0, st;
    mipemu_net_stats(n, 1, &st0);
    slots(n, 1);                            /* the slot whose poll (carrying 5) is lost */
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.lost_down, 1);
    CHECK_EQ(st.tel_up, st0.tel_up);        /* the station stayed silent */
    CHECK_EQ(reg1(n, 1, 1, 2198), 0x12);    /* its block not sent */
    CHECK_EQ(reg1(n, 0, 1, 2), 0x10);       /* the MDP's block sent, unconfirmed */
    CHECK_EQ(reg1(n, 1, 1, 2199), 0);
    CHECK(strstr(tr.buf, "\"r0\":5,\"lost\":true,\"fate\":\"lost\"") != NULL);
    slots(n, 1);
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.blocks_down, 1);
    CHECK_EQ(st.dup_down, 0);
    CHECK_EQ(st.confirmed_down, 1);
    CHECK_EQ(st.blocks_up, 1);
    CHECK_EQ(st.confirmed_up, 1);
    CHECK_EQ(reg1(n, 1, 1, 2200), 5);
    CHECK_EQ(reg1(n, 0, 1, 200), 6);
    CHECK_EQ(sc.calls_down, 2);
    CHECK_EQ(sc.r0_down[1], 5);
    CHECK_EQ(sc.calls_up, 1);
    CHECK_EQ(sc.station, 1);
    mipemu_net_free(n);
    free(tr.buf);

    /* a lost answer: its block and the confirmation of the poll's block it carries are lost:
     * both blocks are sent again, the station gets the MDP's block twice */
    script_t sc2 = { .up = { MIPEMU_FATE_LOST } };
    tr = (sink_t){ 0 };
    n = mk_scripted(&sc2, &tr);
    both_in_next_slot(n, d, 2, u, 2);
    slots(n, 1);
    CHECK_EQ(reg1(n, 1, 1, 2198) & 0x12, 0x10); /* sent, unconfirmed */
    CHECK_EQ(reg1(n, 0, 1, 2), 0x10);           /* nothing received, own block unconfirmed */
    slots(n, 1);
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.lost_up, 1);
    CHECK_EQ(st.blocks_up, 1);
    CHECK_EQ(st.dup_up, 0);
    CHECK_EQ(st.blocks_down, 2);
    CHECK_EQ(st.dup_down, 1);
    CHECK_EQ(st.confirmed_down, 1);
    CHECK_EQ(st.confirmed_up, 1);
    CHECK_EQ(reg1(n, 0, 1, 2), 0x01);
    CHECK_EQ(sc2.calls_up, 2);
    CHECK_EQ(sc2.r0_up[0], 6);
    CHECK_EQ(sc2.r0_up[1], 6);
    CHECK_EQ(sc2.len_up, 2);
    CHECK(strstr(tr.buf, "\"r0\":6,\"lost\":true,\"ack\":true,\"fate\":\"lost\"") != NULL);
    mipemu_net_free(n);
    free(tr.buf);
}

static void t_fate_dup(void)
{
    /* downlink: the block arrives, the answer (with the station's block) too, only the
     * confirmation of the downlink block is lost: it is delivered again at the next poll */
    script_t sc = { .down = { MIPEMU_FATE_DUP } };
    sink_t tr = { 0 };
    mipemu_net *n = mk_scripted(&sc, &tr);
    uint16_t d[2] = { 8, 88 }, u[1] = { 9 };
    both_in_next_slot(n, d, 2, u, 1);
    slots(n, 1);
    mipemu_stats st;
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.blocks_down, 1);
    CHECK_EQ(st.confirmed_down, 0);
    CHECK_EQ(st.blocks_up, 1);              /* the other direction is not lost */
    CHECK_EQ(st.confirmed_up, 1);
    CHECK_EQ(st.lost_up + st.lost_down, 0);
    CHECK_EQ(reg1(n, 0, 1, 2), 0x11);       /* got 9; own block still unconfirmed */
    CHECK_EQ(reg1(n, 0, 1, 1) & MIPEMU_ST_DOWN_RESEND, MIPEMU_ST_DOWN_RESEND);
    CHECK_EQ(reg1(n, 1, 1, 2198), 0x01);    /* got 8; own block confirmed */
    CHECK_EQ(reg1(n, 1, 1, 2200), 8);       /* (this read clears bit 0) */
    CHECK(strstr(tr.buf, "\"r0\":8,\"lost\":false,\"fate\":\"dup\"") != NULL);
    slots(n, 1);
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.blocks_down, 2);
    CHECK_EQ(st.dup_down, 1);
    CHECK_EQ(st.confirmed_down, 1);
    CHECK_EQ(reg1(n, 1, 1, 2198), 0x01);    /* delivered again */
    CHECK_EQ(reg1(n, 0, 1, 2) & 0x10, 0);
    CHECK_EQ(sc.calls_down, 2);
    mipemu_net_free(n);
    free(tr.buf);

    /* uplink: the MDP gets the block, the ack is lost: sent and delivered again */
    script_t sc2 = { .up = { MIPEMU_FATE_DUP } };
    tr = (sink_t){ 0 };
    n = mk_scripted(&sc2, &tr);
    uint16_t u2[3] = { 10, 1, 2 };
    both_in_next_slot(n, NULL, 0, u2, 3);
    slots(n, 1);
    CHECK_EQ(reg1(n, 1, 1, 2198) & 0x12, 0x10);
    CHECK_EQ(reg1(n, 0, 1, 2), 0x01);
    CHECK(strstr(tr.buf, "\"kind\":\"ack\",\"dir\":\"down\",\"st\":1") != NULL);
    CHECK(strstr(tr.buf, "\"regs\":0,\"lost\":true,\"fate\":\"dup\"") != NULL);
    slots(n, 1);
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.blocks_up, 2);
    CHECK_EQ(st.dup_up, 1);
    CHECK_EQ(st.confirmed_up, 1);
    CHECK_EQ(st.lost_down, 1);
    CHECK_EQ(st.lost_up, 0);
    CHECK_EQ(reg1(n, 1, 1, 2198) & 0x10, 0);
    mipemu_net_free(n);
    free(tr.buf);
}

static void t_fate_drop(void)
{
    /* confirmed to the sender, never delivered, in either direction */
    script_t sc = { .down = { MIPEMU_FATE_DROP }, .up = { MIPEMU_FATE_DROP } };
    sink_t tr = { 0 };
    mipemu_net *n = mk_scripted(&sc, &tr);
    uint16_t d[2] = { 11, 1 }, u[2] = { 12, 2 };
    both_in_next_slot(n, d, 2, u, 2);
    slots(n, 3);
    mipemu_stats st;
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.blocks_down + st.blocks_up, 0);
    CHECK_EQ(st.confirmed_down, 1);
    CHECK_EQ(st.confirmed_up, 1);
    CHECK_EQ(st.lost_down + st.lost_up, 0);
    CHECK_EQ(reg1(n, 0, 1, 2), 0);          /* nothing received, own block confirmed */
    CHECK_EQ(reg1(n, 0, 1, 9), 0);
    CHECK_EQ(reg1(n, 1, 1, 2198), 0);
    CHECK_EQ(reg1(n, 1, 1, 2199), 0);
    CHECK_EQ(sc.calls_down, 1);
    CHECK_EQ(sc.calls_up, 1);
    CHECK(strstr(tr.buf, "\"r0\":11,\"lost\":false,\"fate\":\"drop\"") != NULL);
    CHECK(strstr(tr.buf, "\"r0\":12,\"lost\":false,\"ack\":true,\"fate\":\"drop\"") != NULL);
    mipemu_net_free(n);
    free(tr.buf);
}

static int ok_fn(void *user, int station, int up, const uint16_t *blk, int len)
{
    (void)station; (void)up; (void)blk; (void)len;
    (*(int *)user)++;
    return 42;   /* not a fate: counts as OK */
}

static void t_fate_ok_changes_nothing(void)
{
    /* a hook that always says OK: the same trace bytes as without one (random losses, bursts,
     * three stations), and lose_record still strikes */
    for (int with_hook = 0; with_hook < 2; with_hook++) {
        mipemu_config c;
        mipemu_config_default(&c);
        c.stations = 3;
        c.loss_down = 0.2;
        c.loss_up = 0.1;
        c.burst = 3;
        c.seed = 99;
        c.lose_record = 3;
        mipemu_net *n = mipemu_net_new(&c, NULL, 0);
        static sink_t ref;
        sink_t s = { 0 };
        int calls = 0;
        g_tid = 0;
        mipemu_net_set_trace(n, sink_fn, &s);
        if (with_hook)
            mipemu_net_set_fate(n, ok_fn, &calls);
        uint16_t v[20];
        for (int i = 0; i < 300; i++) {
            for (int k = 0; k < 20; k++) v[k] = (uint16_t)(i * k + 3 * (k == 0));
            mipemu_net_advance(n, (uint64_t)i * 250000000ULL);
            wr16(n, 1 + i % 3, 1, 2001, 1 + (unsigned)i % 20, v);
            wr16(n, 0, 1 + (unsigned)(i + 1) % 3, 10, 1 + (unsigned)i % 7, v);
        }
        mipemu_stats st;
        mipemu_net_stats(n, 1, &st);
        if (!with_hook) {
            ref = s;
            CHECK(s.len > 10000);
        } else {
            CHECK(calls > 300);
            CHECK_EQ(s.len, ref.len);
            CHECK(s.len == ref.len && memcmp(s.buf, ref.buf, s.len) == 0);
            free(s.buf);
            free(ref.buf);
        }
        mipemu_net_free(n);
    }
    /* lose_record with a hook: struck once, whatever the hook says */
    mipemu_config c;
    mipemu_config_default(&c);
    c.lose_record = 2;
    mipemu_net *n = mipemu_net_new(&c, NULL, 0);
    script_t sc = { 0 };
    mipemu_net_set_fate(n, script_fn, &sc);
    for (uint16_t rec = 1; rec <= 2; rec++) {
        uint16_t v[1] = { rec };
        CHECK_EQ(wr16(n, 1, 1, 2001, 1, v), 0);
        CHECK(wait_reg(n, 1, 1, 2198, 0x10, 0, 5000000000ULL));
    }
    mipemu_stats st;
    mipemu_net_stats(n, 1, &st);
    CHECK_EQ(st.lost_up, 1);
    CHECK_EQ(st.blocks_up, 2);
    CHECK_EQ(sc.calls_up, 3);      /* 1, 2 (lost), 2 */
    mipemu_net_free(n);
}

static void t_inject_and_peek(void)
{
    mipemu_net *n = mk(2, MIPEMU_DYNAMIC, 0, 0, 1);
    sink_t tr = { 0 };
    mipemu_net_set_trace(n, sink_fn, &tr);
    uint16_t b[3] = { 7, 1, 2 }, r[5];
    CHECK_EQ(mipemu_net_inject(n, 0, 2, b, 3), 0);
    CHECK_EQ(mipemu_net_peek(n, 0, 2, 198, 5, r), 0);
    CHECK_EQ(r[0], 1);
    CHECK_EQ(r[1], 3);
    CHECK_EQ(r[2], 7);
    CHECK_EQ(r[4], 2);
    CHECK_EQ(mipemu_net_peek(n, 0, 2, 198, 5, r), 0);
    CHECK_EQ(r[0], 1);                 /* peeking clears nothing */
    CHECK_EQ(reg1(n, 0, 1, 2), 0);     /* station 1 untouched */
    CHECK_EQ(rd(n, 0, 2, 3, 198, 5, r), 0);   /* a Modbus read of it does clear */
    CHECK_EQ(reg1(n, 0, 2, 2), 0);
    uint16_t one[1] = { 9 };
    CHECK_EQ(mipemu_net_inject(n, 2, 0, one, 1), 0);   /* the TRM of station 2 */
    CHECK_EQ(mipemu_net_peek(n, 2, 0, 2198, 3, r), 0);
    CHECK_EQ(r[0], 1);
    CHECK_EQ(r[1], 1);
    CHECK_EQ(r[2], 9);
    CHECK_EQ(mipemu_net_peek(n, 0, 1, 1, 2, r), 0);    /* station status, read status */
    CHECK_EQ(mipemu_net_peek(n, 0, 1, 3, 1, r), -1);   /* outside the map */
    CHECK_EQ(mipemu_net_peek(n, 0, 3, 2, 1, r), -1);   /* no station 3 */
    CHECK_EQ(mipemu_net_peek(n, 3, 0, 2198, 1, r), -1);
    CHECK_EQ(mipemu_net_inject(n, 0, 0, one, 1), -1);
    CHECK_EQ(mipemu_net_inject(n, 1, 0, one, 0), -1);
    CHECK_EQ(mipemu_net_inject(n, 1, 0, one, 149), -1);
    CHECK(strstr(tr.buf, "\"ev\":\"inject\",\"ep\":\"mdp\",\"st\":2,\"regs\":3,\"r0\":7") != NULL);
    mipemu_stats st;
    mipemu_net_stats(n, 2, &st);
    CHECK_EQ(st.blocks_down + st.blocks_up, 0);
    free(tr.buf);
    mipemu_net_free(n);
}

int main(int argc, char **argv)
{
    run("trm_map", t_trm_map);
    run("mdp_map", t_mdp_map);
    run("function_codes", t_function_codes);
    run("quantities", t_quantities);
    run("malformed", t_malformed);
    run("dynamic_write", t_dynamic_write);
    run("uplink_and_new_data", t_uplink_and_new_data);
    run("static_mode", t_static_mode);
    run("loss_rates", t_loss_rates);
    run("burst_loss", t_burst_loss);
    run("slot_timing", t_slot_timing);
    run("lost_poll_timing", t_lost_poll_timing);
    run("replace_before_and_after_send", t_replace_before_and_after_send);
    run("duplicates", t_duplicates);
    run("unreachable", t_unreachable);
    run("determinism", t_determinism);
    run("two_networks", t_two_networks);
    run("bad_config", t_bad_config);
    run("lose_record", t_lose_record);
    run("fate_lost", t_fate_lost);
    run("fate_dup", t_fate_dup);
    run("fate_drop", t_fate_drop);
    run("fate_ok_changes_nothing", t_fate_ok_changes_nothing);
    run("inject_and_peek", t_inject_and_peek);
    return unit_finish(argc, argv, "emulator unit");
}
