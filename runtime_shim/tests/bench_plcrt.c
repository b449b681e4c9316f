/* Benchmark figures of the plcrt core (printed, never asserted): virtual scans per second,
 * and Modbus requests per second in virtual time over the socketpair seam (server answering
 * in the after_send hook, same thread) and over TCP on 127.0.0.1. BENCH_QUICK=1: short. */
#include "plcrt.h"
#include "testserver.h"

#include <stdio.h>
#include <time.h>

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

static void quiet(void *user, const char *line) { (void)user; (void)line; }

static plcrt_t *new_rt(void)
{
    char err[256];
    plcrt_t *rt = plcrt_new(plcrt_linked_program(), err, sizeof err);
    if (!rt) { fprintf(stderr, "%s\n", err); exit(1); }
    plcrt_set_log(rt, quiet, NULL);
    return rt;
}

typedef struct seam { server_t *srv; int fd; } seam_t;
static void answer(void *user)
{
    seam_t *t = user;
    server_serve_fd(t->srv, t->fd);
}

/* a cycle read of 125 and a cycle write of 123 registers every scan (period = tick) */
static const char *RANGES =
    "[master]\npolling_period = 10ms\n"
    "[device dev]\nhost = 127.0.0.1\nport = %d\n"
    "[read r]\ndevice = dev\nstart = 0\nsize = 125\nimage = %%IW200\n"
    "[write w]\ndevice = dev\nstart = 0\nsize = 123\nimage = %%QW200\n";

static void bench_modbus(const char *what, int use_pair, long scans)
{
    server_t *s = server_new(!use_pair);
    int sv[2] = {-1, -1};
    seam_t t = {s, -1};
    plcrt_t *rt = new_rt();
    char cfg[1024];
    snprintf(cfg, sizeof cfg, RANGES, use_pair ? 1 : s->port);
    if (plcrt_load_config_text(rt, "bench.cfg", cfg) != 0) { fprintf(stderr, "%s\n", plcrt_errmsg(rt)); exit(1); }
    if (use_pair) {
        socketpair(AF_UNIX, SOCK_STREAM, 0, sv);
        t.fd = sv[1];
        plcrt_device_set_fd(rt, "dev", sv[0], answer, &t);
    }
    double t0 = now_s();
    plcrt_scan(rt, (uint64_t)scans);
    double dt = now_s() - t0;
    uint64_t errors, requests, connects;
    plcrt_device_stats(rt, 0, &errors, &requests, &connects);
    printf("bench runtime_shim: %-32s %8.0f requests/s (%llu requests, %llu errors, %.2f s)\n", what,
           requests / dt, (unsigned long long)requests, (unsigned long long)errors, dt);
    plcrt_free(rt);
    if (use_pair) { close(sv[0]); close(sv[1]); }
    server_free(s);
}

int main(void)
{
    int quick = getenv("BENCH_QUICK") && *getenv("BENCH_QUICK") && strcmp(getenv("BENCH_QUICK"), "0");
    long n = quick ? 100000 : 2000000;
    plcrt_t *rt = new_rt();
    double t0 = now_s();
    plcrt_scan(rt, (uint64_t)n);
    double dt = now_s() - t0;
    printf("bench runtime_shim: %-32s %8.0f scans/s (%ld scans of a tiny program, %.2f s)\n",
           "virtual scans, no I/O", n / dt, n, dt);
    plcrt_free(rt);
    bench_modbus("virtual, socketpair seam", 1, quick ? 2000 : 20000);
    bench_modbus("virtual, TCP 127.0.0.1", 0, quick ? 1000 : 10000);
    return 0;
}
