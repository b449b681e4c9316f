/* Unit tests of libmipcosim with scripted fake PLCs (no plcrt): each fake "scan" sends one
 * Modbus request through its socketpair, lets the hook answer, and reads the answer. */
#include "mipcosim.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

static int g_pass, g_fail;
static FILE *g_junit;
static char g_cases[65536];
static size_t g_cases_len;
static const char *g_test;
static int g_test_failed;

#define CHECK(cond)                                                                      \
    do {                                                                                 \
        if (!(cond)) {                                                                   \
            fprintf(stderr, "%s:%d: %s: check failed: %s\n", __FILE__, __LINE__, g_test, \
                    #cond);                                                              \
            g_test_failed = 1;                                                           \
            return;                                                                      \
        }                                                                                \
    } while (0)

/* A fake PLC: scans count, every scan writes a request (FC3 or FC16) and reads the answer. */
typedef struct fake {
    int fd;
    mipcosim_after_send_fn hook;
    void *user;
    int scans;
    uint64_t *log_time;          /* virtual time of each scan, filled by the test */
    mipcosim *sim;
    int fc16_every;              /* 0: reads only */
    uint16_t seq;                /* tapped word */
    uint16_t hdr[3];
    uint16_t data[8];
    uint8_t last_resp[300];
    long last_len;
    int fail_at;                 /* scan number that returns -1 (0: never) */
} fake_t;

static int fake_set_fd(void *rt, const char *device, int fd, mipcosim_after_send_fn hook, void *user)
{
    (void)device;
    fake_t *f = rt;
    f->fd = fd;
    f->hook = hook;
    f->user = user;
    return 0;
}

static int fake_scan(void *rt, uint64_t n)
{
    fake_t *f = rt;
    (void)n;
    f->scans++;
    if (f->fail_at && f->scans == f->fail_at) return -1;
    if (f->log_time) f->log_time[f->scans - 1] = mipcosim_now(f->sim);
    if (f->fd < 0) return 0;
    uint8_t req[300];
    size_t len;
    if (f->fc16_every && f->scans % f->fc16_every == 0) {
        /* FC16 of 3 registers at TRM 2001: 42, scan, 7 */
        uint8_t r[] = {0, 1, 0, 0, 0, 13, 1, 16, 0x07, 0xD1, 0, 3, 6, 0, 42, 0, (uint8_t)f->scans, 0, 7};
        memcpy(req, r, sizeof r);
        len = sizeof r;
    } else {
        /* FC3 of 5 at TRM 2198 (status, count, 3 data) */
        uint8_t r[] = {0, 2, 0, 0, 0, 6, 1, 3, 0x08, 0x96, 0, 5};
        memcpy(req, r, sizeof r);
        len = sizeof r;
    }
    if (send(f->fd, req, len, 0) != (ssize_t)len) return -1;
    f->hook(f->user);
    f->last_len = recv(f->fd, f->last_resp, sizeof f->last_resp, MSG_DONTWAIT);
    if (f->last_len <= 0) return -1;
    f->seq++;
    f->hdr[0] = (uint16_t)f->scans;
    f->hdr[1] = 3;
    for (int i = 0; i < 3; i++) f->data[i] = (uint16_t)(f->scans * 10 + i);
    return 0;
}

/* The same fake over the in-process transport: the ADU goes to the handler, no socket. */
typedef struct fake_ip {
    mipcosim_transact_fn transact;
    void *user;
    int scans;
    uint8_t req[300];
    size_t req_len;
    uint8_t rsp[400];
    long rsp_len;
} fake_ip_t;

static int fake_set_transport(void *rt, const char *device, mipcosim_transact_fn transact, void *user)
{
    (void)device;
    fake_ip_t *f = rt;
    f->transact = transact;
    f->user = user;
    return 0;
}

static int fake_ip_scan(void *rt, uint64_t n)
{
    fake_ip_t *f = rt;
    (void)n;
    f->scans++;
    if (!f->transact) return 0;
    f->rsp_len = f->transact(f->user, f->req, f->req_len, f->rsp, sizeof f->rsp);
    return 0;
}

static mipcosim *new_sim(int stations, double loss, uint64_t seed)
{
    char err[128];
    mipcosim *sim = mipcosim_new_args(stations, 0, 148, loss, loss, 0, seed, 1000000, 1000000, 12,
                                      err, sizeof err);
    if (!sim) fprintf(stderr, "mipcosim_new: %s\n", err);
    return sim;
}

static void fake_init(fake_t *f, mipcosim *sim)
{
    memset(f, 0, sizeof *f);
    f->fd = -1;
    f->sim = sim;
}

/* ------------------------------------------------------------------ tests */

static void test_ticks_in_lockstep(void)
{
    mipcosim *sim = new_sim(1, 0, 1);
    CHECK(sim);
    fake_t a, b;
    uint64_t ta[200], tb[200];
    fake_init(&a, sim);
    fake_init(&b, sim);
    a.log_time = ta;
    b.log_time = tb;
    CHECK(mipcosim_plc_add(sim, fake_scan, &a, 10000000) == 0);
    CHECK(mipcosim_plc_add(sim, fake_scan, &b, 25000000) == 1);
    CHECK(mipcosim_run(sim, 100000000) == 0);   /* 0..90 ms: 10 scans; 0, 25, 50, 75: 4 */
    CHECK(a.scans == 10 && b.scans == 4);
    CHECK(ta[9] == 90000000 && tb[3] == 75000000);
    CHECK(mipcosim_now(sim) == 100000000);
    CHECK(mipcosim_scans(sim) == 14);
    CHECK(mipcosim_run(sim, 50000000) == -1);   /* backwards */
    CHECK(strstr(mipcosim_errmsg(sim), "before now"));
    mipcosim_free(sim);
}

static void test_requests_answered_by_the_emulator(void)
{
    mipcosim *sim = new_sim(2, 0, 1);
    CHECK(sim);
    fake_t a;
    fake_init(&a, sim);
    a.fc16_every = 5;
    int id = mipcosim_plc_add(sim, fake_scan, &a, 10000000);
    CHECK(mipcosim_connect(sim, id, fake_set_fd, "trm", 2) == 0);
    CHECK(mipcosim_connect(sim, id, fake_set_fd, "x", 3) == -1);   /* no station 3 */
    CHECK(strstr(mipcosim_errmsg(sim), "endpoint 3"));
    CHECK(mipcosim_run(sim, 20000000) == 0);
    /* the answer to FC3: unit 1, fc 3, 10 bytes */
    CHECK(a.last_len == 9 + 10 && a.last_resp[7] == 3 && a.last_resp[8] == 10);
    CHECK(mipcosim_run(sim, 60000000) == 0);   /* scan 5 wrote a block */
    CHECK(mipcosim_requests(sim) == 6);
    mipemu_stats st;
    CHECK(mipemu_net_stats(mipcosim_net(sim), 2, &st) == 0);
    CHECK(st.blocks_up == 1);                 /* the radio carried it to the MDP */
    mipcosim_free(sim);
}

static void test_inproc_transport_answers_adus(void)
{
    mipcosim *sim = new_sim(2, 0, 1);
    CHECK(sim);
    fake_ip_t a;
    memset(&a, 0, sizeof a);
    /* FC3 of 5 at TRM 2198 (status, count, 3 data), transaction id 7 */
    uint8_t r[] = {0, 7, 0, 0, 0, 6, 1, 3, 0x08, 0x96, 0, 5};
    memcpy(a.req, r, sizeof r);
    a.req_len = sizeof r;
    int id = mipcosim_plc_add(sim, fake_ip_scan, &a, 10000000);
    CHECK(mipcosim_connect_inproc(sim, id, fake_set_transport, "trm", 2) == 0);
    CHECK(mipcosim_connect_inproc(sim, id, fake_set_transport, "x", 3) == -1);
    CHECK(strstr(mipcosim_errmsg(sim), "endpoint 3"));
    CHECK(mipcosim_run(sim, 20000000) == 0);
    /* MBAP echoes the transaction id; unit 1, fc 3, 10 bytes */
    CHECK(a.rsp_len == 9 + 10 && a.rsp[1] == 7 && a.rsp[7] == 3 && a.rsp[8] == 10);
    CHECK(mipcosim_requests(sim) == 2);
    /* a frame whose MBAP length does not match: no answer (a timeout for the runtime) */
    a.req[5] = 9;
    CHECK(mipcosim_run(sim, 30000000) == 0);
    CHECK(a.rsp_len == -1 && mipcosim_requests(sim) == 2);
    mipcosim_free(sim);
}

/* A participant that is not a plcrt PLC: its scan makes its own requests (mipcosim_request). */
typedef struct peer_part {
    mipcosim *sim;
    int ep;
    int scans;
    uint64_t t_last;
    long rsp_len;
    uint8_t rsp[MIPEMU_RESPONSE_MAX];
} peer_part_t;

static int peer_part_scan(void *rt, uint64_t n)
{
    peer_part_t *p = rt;
    (void)n;
    /* FC3 of 5 at TRM 2198, transaction id = scan number */
    uint8_t r[] = {0, (uint8_t)++p->scans, 0, 0, 0, 6, 1, 3, 0x08, 0x96, 0, 5};
    p->t_last = mipcosim_now(p->sim);
    p->rsp_len = mipcosim_request(p->sim, p->ep, r, sizeof r, p->rsp, sizeof p->rsp);
    return p->rsp_len < 0 ? -1 : 0;
}

static void test_request_of_a_participant_at_the_current_time(void)
{
    char path[] = "/tmp/mipcosim-request-XXXXXX";
    int fd = mkstemp(path);
    CHECK(fd >= 0);
    close(fd);
    mipcosim *sim = new_sim(2, 0, 1);
    CHECK(sim);
    CHECK(mipcosim_trace_file(sim, path) == 0);
    uint8_t rsp[MIPEMU_RESPONSE_MAX];
    /* between runs: FC16 of 3 registers at TRM 2001 of station 2 (tid 9), at 50 ms */
    CHECK(mipcosim_run(sim, 50000000) == 0);
    uint8_t w[] = {0, 9, 0, 0, 0, 13, 1, 16, 0x07, 0xD1, 0, 3, 6, 0, 42, 0, 43, 0, 44};
    long n = mipcosim_request(sim, 2, w, sizeof w, rsp, sizeof rsp);
    CHECK(n == 12 && rsp[1] == 9 && rsp[7] == 16);
    CHECK(mipcosim_requests(sim) == 1);
    /* the radio carries the block to the MDP: its read (unit 2) finds it */
    CHECK(mipcosim_run(sim, 500000000) == 0);
    uint8_t r[] = {0, 10, 0, 0, 0, 6, 2, 3, 0, 198, 0, 5};
    n = mipcosim_request(sim, 0, r, sizeof r, rsp, sizeof rsp);
    CHECK(n == 9 + 10 && rsp[6] == 2 && rsp[8] == 10);
    CHECK((rsp[9] << 8 | rsp[10]) & MIPEMU_RS_NEW_DATA);
    CHECK((rsp[11] << 8 | rsp[12]) == 3 && (rsp[13] << 8 | rsp[14]) == 42);
    /* refused: no such endpoint, a short response buffer, not one whole frame (not counted) */
    CHECK(mipcosim_request(sim, 3, r, sizeof r, rsp, sizeof rsp) == -1);
    CHECK(strstr(mipcosim_errmsg(sim), "endpoint 3"));
    CHECK(mipcosim_request(sim, 0, r, sizeof r, rsp, 20) == -1);
    CHECK(mipcosim_request(sim, 0, r, sizeof r - 1, rsp, sizeof rsp) == -1);
    CHECK(strstr(mipcosim_errmsg(sim), "whole"));
    CHECK(mipcosim_requests(sim) == 2);
    /* from a scan function during mipcosim_run: at the scan's virtual time */
    peer_part_t p;
    memset(&p, 0, sizeof p);
    p.sim = sim;
    p.ep = 1;
    CHECK(mipcosim_plc_add(sim, peer_part_scan, &p, 20000000) == 0);
    CHECK(mipcosim_run(sim, 560000000) == 0);                 /* 500, 520, 540 ms */
    CHECK(p.scans == 3 && p.t_last == 540000000);
    CHECK(p.rsp_len == 9 + 10 && p.rsp[1] == 3);
    CHECK(mipcosim_requests(sim) == 5);
    mipcosim_free(sim);                                        /* closes the trace */
    static char trace[1 << 16];
    FILE *f = fopen(path, "r");
    CHECK(f);
    size_t len = fread(trace, 1, sizeof trace - 1, f);
    trace[len] = 0;
    fclose(f);
    unlink(path);
    /* each request is traced at the virtual time it was made */
    CHECK(strstr(trace, "{\"t\":50000000,") && strstr(trace, "\"ev\":\"modbus\",\"ep\":\"trm\",\"st\":2"));
    CHECK(strstr(trace, "{\"t\":540000000,"));
}

static void test_taps_log_each_change_once(void)
{
    mipcosim *sim = new_sim(1, 0, 1);
    CHECK(sim);
    fake_t a;
    fake_init(&a, sim);
    int id = mipcosim_plc_add(sim, fake_scan, &a, 10000000);
    CHECK(mipcosim_connect(sim, id, fake_set_fd, "trm", 1) == 0);
    CHECK(mipcosim_tap(sim, 5, id, &a.seq, a.hdr, 2, 1, a.data, 8) == 0);
    CHECK(mipcosim_tap(sim, 64, id, &a.seq, a.hdr, 2, 1, a.data, 8) == -1);
    CHECK(mipcosim_run(sim, 30000000) == 0);  /* 3 scans, 3 changes */
    uint16_t buf[64];
    size_t n = mipcosim_tap_read(sim, buf, 64);
    CHECK(n == 3 * (3 + 2 + 3 + 1));
    CHECK(buf[0] == 5 && buf[1] == id && buf[2] == 6 && buf[3] == 1 && buf[5] == 10);
    CHECK(buf[8] == a.seq - 2);                     /* the seq value ends each entry */
    CHECK(buf[9 + 3] == 2 && buf[9 + 5] == 20 && buf[9 + 7] == 22 && buf[9 + 8] == a.seq - 1);
    CHECK(mipcosim_tap_read(sim, buf, 64) == 0);
    /* a buffer too small for one entry gets none, and nothing is lost */
    CHECK(mipcosim_run(sim, 40000000) == 0);
    CHECK(mipcosim_tap_read(sim, buf, 4) == 0);
    CHECK(mipcosim_tap_read(sim, buf, 64) == 9);
    mipcosim_untap(sim, 5);
    CHECK(mipcosim_run(sim, 60000000) == 0);
    CHECK(mipcosim_tap_read(sim, buf, 64) == 0);
    mipcosim_free(sim);
}

static void test_replace_switches_off_and_restarts(void)
{
    mipcosim *sim = new_sim(1, 0, 1);
    CHECK(sim);
    fake_t a, b;
    fake_init(&a, sim);
    fake_init(&b, sim);
    int id = mipcosim_plc_add(sim, fake_scan, &a, 10000000);
    CHECK(mipcosim_connect(sim, id, fake_set_fd, "trm", 1) == 0);
    int fd_first = a.fd;
    CHECK(mipcosim_run(sim, 50000000) == 0);
    CHECK(a.scans == 5);
    CHECK(mipcosim_plc_replace(sim, id, NULL, NULL, 0) == 0);     /* off */
    CHECK(mipcosim_run(sim, 100000000) == 0);
    CHECK(a.scans == 5);
    CHECK(mipcosim_plc_replace(sim, id, fake_scan, &b, 10000000) == 0);
    CHECK(mipcosim_connect(sim, id, fake_set_fd, "trm", 1) == 0);
    CHECK(b.fd == fd_first);                                       /* same socketpair */
    CHECK(mipcosim_run(sim, 130000000) == 0);                      /* 100, 110, 120 */
    CHECK(b.scans == 3 && a.scans == 5);
    CHECK(b.last_len == 19);
    mipcosim_free(sim);
}

static void test_failed_scan_stops_the_run(void)
{
    mipcosim *sim = new_sim(1, 0, 1);
    CHECK(sim);
    fake_t a;
    fake_init(&a, sim);
    a.fail_at = 3;
    int id = mipcosim_plc_add(sim, fake_scan, &a, 10000000);
    CHECK(mipcosim_run(sim, 100000000) == -1);
    CHECK(mipcosim_failed_plc(sim) == id);
    CHECK(mipcosim_now(sim) == 20000000);
    mipcosim_free(sim);
}

static void trace_run(uint64_t seed, char *out, size_t cap)
{
    char path[] = "/tmp/mipcosim-trace-XXXXXX";
    int fd = mkstemp(path);
    close(fd);
    mipcosim *sim = new_sim(1, 0.3, seed);
    fake_t a;
    fake_init(&a, sim);
    a.fc16_every = 3;
    int id = mipcosim_plc_add(sim, fake_scan, &a, 10000000);
    mipcosim_connect(sim, id, fake_set_fd, "trm", 1);
    mipcosim_trace_file(sim, path);
    mipcosim_run(sim, 2000000000ull);
    mipcosim_free(sim);
    FILE *f = fopen(path, "r");
    size_t n = f ? fread(out, 1, cap - 1, f) : 0;
    out[n] = 0;
    if (f) fclose(f);
    unlink(path);
}

static void test_same_seed_same_trace(void)
{
    static char t1[1 << 20], t2[1 << 20], t3[1 << 20];
    trace_run(9, t1, sizeof t1);
    trace_run(9, t2, sizeof t2);
    trace_run(10, t3, sizeof t3);
    CHECK(strlen(t1) > 10000);
    CHECK(strcmp(t1, t2) == 0);
    CHECK(strcmp(t1, t3) != 0);
    CHECK(strstr(t1, "\"lost\":true"));
}

/* ------------------------------------------------------------------ runner */

/* The library exports the core's API (tests/st_lib drives the network with it): a fate hook
 * that drops the station's block, injection and peeking, on the simulation's network. */
static int drop_up(void *user, int station, int up, const uint16_t *blk, int len)
{
    (void)station; (void)blk; (void)len;
    (*(int *)user)++;
    return up ? MIPEMU_FATE_DROP : MIPEMU_FATE_OK;
}

static void test_core_api_exported(void)
{
    mipcosim *sim = new_sim(1, 0.0, 1);
    CHECK(sim);
    mipemu_net *net = mipcosim_net(sim);
    int calls = 0;
    mipemu_net_set_fate(net, drop_up, &calls);
    uint16_t blk[2] = { 3, 4 }, r[4];
    CHECK(mipemu_net_inject(net, 1, 0, blk, 2) == 0);      /* into the TRM's read area */
    CHECK(mipemu_net_peek(net, 1, 0, 2198, 4, r) == 0);
    CHECK(r[0] == 1 && r[1] == 2 && r[2] == 3 && r[3] == 4);
    uint8_t req[] = {0, 1, 0, 0, 0, 11, 1, 16, 0x07, 0xD1, 0, 2, 4, 0, 9, 0, 9};  /* FC16 2001: 9, 9 */
    uint8_t rsp[MIPEMU_RESPONSE_MAX];
    CHECK(mipemu_handle(net, 1, req, sizeof req, rsp, sizeof rsp) == 12);
    CHECK(mipemu_net_advance(net, 100000000ULL) == 0);
    CHECK(calls >= 1);
    CHECK(mipemu_net_peek(net, 1, 0, 2198, 1, r) == 0 && r[0] == 1);   /* confirmed, bit 0 kept */
    CHECK(mipemu_net_peek(net, 0, 1, 2, 1, r) == 0 && r[0] == 0);       /* dropped: nothing at the MDP */
    mipcosim_free(sim);
}

/* A relay in the kernel (issue 35): its scripted events happen at their virtual times; a
 * PLC's device reads it in process; a wrong configuration is one line. */
static void test_relay_in_virtual_time(void)
{
    mipcosim *sim = new_sim(1, 0, 1);
    CHECK(sim);
    siprotec_config cfg;
    siprotec_config_default(&cfg);
    cfg.time_origin_ms = 1000;
    int rid = mipcosim_relay_add(sim, &cfg);
    CHECK(rid == 0 && mipcosim_relay(sim, rid) != NULL && mipcosim_relay(sim, 1) == NULL);
    const uint16_t w[4] = {0x0102, 101, 0x0101, 1};
    CHECK(siprotec_script(mipcosim_relay(sim, rid), 25000000, w) == 0);     /* at 25 ms */
    fake_ip_t a;
    memset(&a, 0, sizeof a);
    /* FC3 of 26 at 600 (40601..40626), transaction id 9 */
    uint8_t r[] = {0, 9, 0, 0, 0, 6, 1, 3, 0x02, 0x58, 0, 26};
    memcpy(a.req, r, sizeof r);
    a.req_len = sizeof r;
    int id = mipcosim_plc_add(sim, fake_ip_scan, &a, 10000000);
    CHECK(mipcosim_connect_relay(sim, id, fake_set_transport, "relay", rid) == 0);
    CHECK(mipcosim_connect_relay(sim, id, fake_set_transport, "x", 5) == -1);
    CHECK(strstr(mipcosim_errmsg(sim), "no relay 5"));
    CHECK(mipcosim_run(sim, 20000000) == 0);               /* scans at 0 and 10 ms: nothing yet */
    CHECK(a.rsp_len == 9 + 52 && a.rsp[1] == 9 && a.rsp[9] == 0 && a.rsp[10] == 0);
    CHECK(mipcosim_run(sim, 40000000) == 0);               /* the scan at 30 ms sees the entry */
    CHECK(a.rsp[10] == 1 && a.rsp[11] == 1 && a.rsp[12] == 1);   /* count 1, SOE_Control 257 */
    CHECK(a.rsp[13] == 0x01 && a.rsp[14] == 0x02);         /* type 1 bit 2 */
    CHECK(a.rsp[27] == 0x04 && a.rsp[28] == 0x01);         /* time stamp 1000 + 25 ms (least significant word) */
    siprotec_stats st;
    siprotec_get_stats(mipcosim_relay(sim, rid), &st);
    CHECK(st.entries == 1 && st.seq == 1 && st.offered == 1);
    uint8_t ack[] = {0, 2, 0, 0, 0, 6, 1, 6, 0x02, 0x59, 0x01, 0x01};  /* FC6 601: 1 + 256 */
    uint8_t rsp[SIPROTEC_RESPONSE_MAX];
    CHECK(mipcosim_relay_request(sim, rid, ack, sizeof ack, rsp, sizeof rsp) == 12);
    siprotec_get_stats(mipcosim_relay(sim, rid), &st);
    CHECK(st.entries == 0 && st.acknowledged == 1);
    CHECK(mipcosim_relay_request(sim, 3, ack, sizeof ack, rsp, sizeof rsp) == -1);
    cfg.seq_bits = 1;
    CHECK(mipcosim_relay_add(sim, &cfg) == -1 && strstr(mipcosim_errmsg(sim), "relay: "));
    mipcosim_free(sim);
}

static void run(const char *name, void (*fn)(void))
{
    g_test = name;
    g_test_failed = 0;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    fn();
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double s = (double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) / 1e9;
    if (g_test_failed) g_fail++;
    else g_pass++;
    g_cases_len += (size_t)snprintf(g_cases + g_cases_len, sizeof g_cases - g_cases_len,
                                    "  <testcase classname=\"cosim\" name=\"%s\" time=\"%.3f\">%s</testcase>\n",
                                    name, s, g_test_failed ? "<failure message=\"check failed (see stderr)\"/>" : "");
    printf("%s %s\n", g_test_failed ? "FAIL" : "ok  ", name);
}

int main(int argc, char **argv)
{
    const char *junit = NULL;
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--junit") && i + 1 < argc) junit = argv[++i];
    run("ticks_in_lockstep", test_ticks_in_lockstep);
    run("requests_answered_by_the_emulator", test_requests_answered_by_the_emulator);
    run("inproc_transport_answers_adus", test_inproc_transport_answers_adus);
    run("request_of_a_participant_at_the_current_time",
        test_request_of_a_participant_at_the_current_time);
    run("taps_log_each_change_once", test_taps_log_each_change_once);
    run("replace_switches_off_and_restarts", test_replace_switches_off_and_restarts);
    run("failed_scan_stops_the_run", test_failed_scan_stops_the_run);
    run("same_seed_same_trace", test_same_seed_same_trace);
    run("core_api_exported", test_core_api_exported);
    run("relay_in_virtual_time", test_relay_in_virtual_time);
    printf("cosim-unit: %d passed, %d failed\n", g_pass, g_fail);
    if (junit) {
        g_junit = fopen(junit, "w");
        if (!g_junit) {
            fprintf(stderr, "cannot write %s\n", junit);
            return 1;
        }
        fprintf(g_junit, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                         "<testsuite name=\"cosim-unit\" tests=\"%d\" failures=\"%d\">\n%s</testsuite>\n",
                g_pass + g_fail, g_fail, g_cases);
        fclose(g_junit);
    }
    return g_fail ? 1 : 0;
}
