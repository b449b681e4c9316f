/* Unit tests of the RTU framing of the mip-emulator server (src/rtu.c) with explicit times: a
 * request whose characters are split by a pause, and two requests separated by one, on the
 * line model of the framer (a pure function of bytes and times, no clock). Rules from the
 * MODBUS over Serial Line Specification and Implementation Guide V1.02, section 2.5.1.1: a
 * silence of more than 1.5 characters inside a frame makes it incomplete (discarded, so the
 * slave is silent); a silence of 3.5 characters ends a frame; above 19,200 baud t1.5 = 750 us and
 * t3.5 = 1.75 ms. The pauses of issue 38: 1.4 / 1.6 / 3.4 / 3.6 character times. */
#define _GNU_SOURCE
#include "../src/rtu.h"

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define UNIT_CLASS "emulator.rtu"
#include "unit.h"

/* ---- a bus with one TRM at unit id 1; answers go into a pipe the test reads ---- */

typedef struct line {
    rtu_bus b;
    int rd;           /* the master's side: what the slave wrote */
    int requests;     /* frames handed to the core */
} line_t;

/* the core's stand-in: FC3 of one register answers 42 */
static long fake_core(void *user, int ep, uint64_t at_ns, const uint8_t *req, size_t len, uint8_t *resp,
                      size_t cap)
{
    (void)ep; (void)at_ns; (void)cap;
    line_t *l = user;
    l->requests++;
    if (len < 8) return -1;
    memcpy(resp, req, 6);
    resp[5] = 5; /* unit + 4 */
    resp[6] = req[6];
    resp[7] = req[7];
    resp[8] = 2;
    resp[9] = 0;
    resp[10] = 42;
    return 11;
}

static void line_open(line_t *l, const char *spec)
{
    memset(l, 0, sizeof *l);
    char err[160];
    if (rtu_parse(&l->b, spec, 1, err, sizeof err) < 0) {
        fprintf(stderr, "%s\n", err);
        exit(2);
    }
    int p[2];
    if (pipe2(p, O_NONBLOCK) < 0) exit(2);
    l->rd = p[0];
    l->b.fd = p[1];
}

static void line_close(line_t *l)
{
    close(l->rd);
    close(l->b.fd);
}

static void feed(line_t *l, const uint8_t *p, size_t n, uint64_t t) { rtu_feed(&l->b, p, n, t, fake_core, l); }

/* runs every deadline up to t, as the server's timer does */
static void run_until(line_t *l, uint64_t t)
{
    for (uint64_t d; (d = rtu_next_deadline(&l->b)) <= t;)
        rtu_on_time(&l->b, d, fake_core, l);
}

/* answers the slave wrote so far (each 7 bytes: 01 03 02 00 2A CRC) */
static int answers(line_t *l)
{
    uint8_t buf[512];
    ssize_t n = read(l->rd, buf, sizeof buf);
    if (n <= 0) return 0;
    for (ssize_t i = 0; i + 7 <= n; i += 7) {
        uint16_t crc = rtu_crc16(buf + i, 5);
        if (buf[i] != 1 || buf[i + 1] != 3 || buf[i + 4] != 42 || buf[i + 5] != (uint8_t)crc ||
            buf[i + 6] != (uint8_t)(crc >> 8))
            return -1;
    }
    return n % 7 ? -1 : (int)(n / 7);
}

static const uint8_t REQ[8] = { 0x01, 0x03, 0x07, 0xD0, 0x00, 0x01, 0x84, 0x87 }; /* FC3 2000, 1 */
#define T0 1000000000ull

/* the request, its first k characters written at T0, the rest when they have crossed the wire
 * and a silence of pause_ns followed */
static int split_request(const char *spec, size_t k, uint64_t pause_ns)
{
    line_t l;
    line_open(&l, spec);
    uint64_t c = rtu_char_ns(&l.b);
    feed(&l, REQ, k, T0);
    feed(&l, REQ + k, sizeof REQ - k, T0 + k * c + pause_ns);
    run_until(&l, T0 + 10000000000ull);
    int got = answers(&l);
    CHECK_EQ(l.requests, got); /* a frame the core got is answered; a broken one reaches nothing */
    line_close(&l);
    return got;
}

/* two whole requests, the second written when the first has crossed the wire and a silence of
 * pause_ns followed */
static int two_requests(const char *spec, uint64_t pause_ns)
{
    line_t l;
    line_open(&l, spec);
    uint64_t c = rtu_char_ns(&l.b);
    feed(&l, REQ, sizeof REQ, T0);
    feed(&l, REQ, sizeof REQ, T0 + sizeof REQ * c + pause_ns);
    run_until(&l, T0 + 10000000000ull);
    int got = answers(&l);
    line_close(&l);
    return got;
}

static const struct { const char *spec; const char *name; } LINES[] = {
    { "pty:9600:8N1=trm1@1", "9600 8N1" },
    { "pty:19200:8E1=trm1@1", "19200 8E1" },
    { "pty:1200:8O1=trm1@1", "1200 8O1" },
};

static void test_pauses_in_character_times(void)
{
    for (size_t i = 0; i < sizeof LINES / sizeof LINES[0]; i++) {
        line_t l;
        line_open(&l, LINES[i].spec);
        uint64_t c = rtu_char_ns(&l.b);
        line_close(&l);
        for (size_t k = 1; k < sizeof REQ; k += 3) {
            snprintf(g_case, sizeof g_case, "%s: a pause of 1.4 characters after character %zu: answered", LINES[i].name, k);
            g_case_failed = 0;
            CHECK_EQ(split_request(LINES[i].spec, k, c * 14 / 10), 1);
            end_case();
            snprintf(g_case, sizeof g_case, "%s: a pause of 1.6 characters after character %zu: silence", LINES[i].name, k);
            g_case_failed = 0;
            CHECK_EQ(split_request(LINES[i].spec, k, c * 16 / 10), 0);
            end_case();
            snprintf(g_case, sizeof g_case, "%s: a pause of 3.4 characters after character %zu: silence", LINES[i].name, k);
            g_case_failed = 0;
            CHECK_EQ(split_request(LINES[i].spec, k, c * 34 / 10), 0);
            end_case();
        }
        snprintf(g_case, sizeof g_case, "%s: two requests 3.4 characters apart are one broken frame: silence", LINES[i].name);
        g_case_failed = 0;
        CHECK_EQ(two_requests(LINES[i].spec, c * 34 / 10), 0);
        end_case();
        snprintf(g_case, sizeof g_case, "%s: two requests 3.6 characters apart are two frames: two answers", LINES[i].name);
        g_case_failed = 0;
        CHECK_EQ(two_requests(LINES[i].spec, c * 36 / 10), 2);
        end_case();
        snprintf(g_case, sizeof g_case, "%s: two requests 1.4 characters apart are one frame of 16 bytes: bad CRC, silence", LINES[i].name);
        g_case_failed = 0;
        CHECK_EQ(two_requests(LINES[i].spec, c * 14 / 10), 0);
        end_case();
    }
}

/* above 19,200 baud the timers are fixed: t1.5 = 750 us, t3.5 = 1.75 ms, whatever the character */
static void test_fixed_timers_above_19200(void)
{
    static const char *specs[] = { "pty:38400:8E1=trm1@1", "pty:115200:8N1=trm1@1", "pty:921600:8E1=trm1@1" };
    for (size_t i = 0; i < 3; i++) {
        snprintf(g_case, sizeof g_case, "%s: pauses of 700 / 800 us inside, 1700 / 1800 us between frames", specs[i]);
        g_case_failed = 0;
        CHECK_EQ(split_request(specs[i], 4, 700000), 1);
        CHECK_EQ(split_request(specs[i], 4, 800000), 0);
        CHECK_EQ(two_requests(specs[i], 1700000), 0);
        CHECK_EQ(two_requests(specs[i], 1800000), 2);
        end_case();
    }
}

/* The frame ends exactly t3.5 after its last character, to the nanosecond, and the answer is
 * written when its last character would have arrived: a gap and its 7 characters later. */
static void test_frame_end_and_answer_to_the_nanosecond(void)
{
    static const struct { const char *spec; uint64_t c, t15, t35; } L[] = {
        { "pty:9600:8N1=trm1@1", 1041666, 1562499, 3645831 },
        { "pty:19200:8E1=trm1@1", 572916, 859374, 2005206 },
        { "pty:115200:8E1=trm1@1", 95486, 750000, 1750000 },
    };
    for (size_t i = 0; i < 3; i++) {
        snprintf(g_case, sizeof g_case, "%s: character, t1.5, t3.5; the frame closes t3.5 after its end", L[i].spec);
        g_case_failed = 0;
        line_t l;
        line_open(&l, L[i].spec);
        CHECK_EQ(rtu_char_ns(&l.b), L[i].c);
        CHECK_EQ(rtu_t15_ns(&l.b), L[i].t15);
        CHECK_EQ(rtu_gap_ns(&l.b), L[i].t35);
        feed(&l, REQ, sizeof REQ, T0);
        uint64_t end = T0 + 8 * L[i].c, close_at = end + L[i].t35;
        CHECK_EQ(rtu_next_deadline(&l.b), close_at);
        rtu_on_time(&l.b, close_at - 1, fake_core, &l);
        CHECK_EQ(l.requests, 0);
        rtu_on_time(&l.b, close_at, fake_core, &l);
        CHECK_EQ(l.requests, 1);
        uint64_t answer_at = end + L[i].t35 + 7 * L[i].c;
        CHECK_EQ(rtu_next_deadline(&l.b), answer_at);
        rtu_on_time(&l.b, answer_at - 1, fake_core, &l);
        CHECK_EQ(answers(&l), 0);
        rtu_on_time(&l.b, answer_at, fake_core, &l);
        CHECK_EQ(answers(&l), 1);
        line_close(&l);
        end_case();
    }
}

/* Bytes that arrive after the frame's t3.5 begin a new frame even when the timer has not run
 * yet (a server woken late): the frame before them is taken first. */
static void test_a_late_timer_does_not_join_frames(void)
{
    snprintf(g_case, sizeof g_case, "19200 8E1: a request arriving after t3.5 with the timer not yet run");
    g_case_failed = 0;
    line_t l;
    line_open(&l, "pty:19200:8E1=trm1@1");
    uint64_t c = rtu_char_ns(&l.b);
    feed(&l, REQ, sizeof REQ, T0);
    uint64_t second = T0 + 8 * c + rtu_gap_ns(&l.b) + 1;
    feed(&l, REQ, sizeof REQ, second); /* no rtu_on_time in between */
    CHECK_EQ(l.requests, 1);
    run_until(&l, second + 1000000000ull);
    CHECK_EQ(l.requests, 2);
    line_close(&l);
    end_case();
}

int main(int argc, char **argv)
{
    test_pauses_in_character_times();
    test_fixed_timers_above_19200();
    test_frame_end_and_answer_to_the_nanosecond();
    test_a_late_timer_does_not_join_frames();
    return unit_finish(argc, argv, "emulator-rtu");
}
