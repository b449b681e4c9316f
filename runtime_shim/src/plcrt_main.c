/* The thin executable: one program linked with the core. */
#include "plcrt.h"

#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static volatile int stop_requested;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

static void usage(FILE *f, const char *argv0)
{
    fprintf(f,
            "usage: %s [-c CONFIG] [-m real|virtual] [-n SCANS] [-s [HOST:]PORT] [--check]\n"
            "  -c CONFIG   Modbus config (plcrt format or OpenPLC mbconfig.cfg)\n"
            "  -m MODE     real (default): absolute deadlines; virtual: as fast as possible\n"
            "  -n SCANS    stop after SCANS scans (default: until SIGINT/SIGTERM; virtual: 1000)\n"
            "  -s ADDR     Modbus TCP slave exposing the image (default host 127.0.0.1)\n"
            "  --check     load the config, report errors, exit\n"
            "  --retain FILE          keep the RETAIN variables in FILE (saved atomically)\n"
            "  --retain-period MS     save every MS ms of scan time (default 1000; 0: on stop only)\n"
            "  --warm | --cold        warm (default): restore FILE if it is a valid snapshot of\n"
            "                         this program; cold: initial values, FILE is overwritten\n",
            argv0);
}

int main(int argc, char **argv)
{
    const char *config = NULL, *slave = NULL;
    int realtime = 1, check = 0;
    unsigned long long scans = 0;
    int scans_given = 0;
    const char *retain = NULL;
    int warm = 1;
    unsigned long long retain_ms = 1000;
    int retain_ms_given = 0;
    static const struct option longopts[] = {
        {"check", no_argument, NULL, 'k'}, {"help", no_argument, NULL, 'h'},
        {"retain", required_argument, NULL, 'R'}, {"retain-period", required_argument, NULL, 'P'},
        {"warm", no_argument, NULL, 'W'}, {"cold", no_argument, NULL, 'C'}, {0, 0, 0, 0}};
    int opt;
    while ((opt = getopt_long(argc, argv, "c:m:n:s:h", longopts, NULL)) != -1) {
        switch (opt) {
        case 'c': config = optarg; break;
        case 'm':
            if (!strcmp(optarg, "real")) realtime = 1;
            else if (!strcmp(optarg, "virtual")) realtime = 0;
            else { fprintf(stderr, "%s: error: -m takes real or virtual\n", argv[0]); return 2; }
            break;
        case 'n': {
            char *end;
            errno = 0;
            scans = strtoull(optarg, &end, 10);
            if (errno || *end || optarg[0] == '-') {
                fprintf(stderr, "%s: error: -n takes a number of scans\n", argv[0]);
                return 2;
            }
            scans_given = 1;
            break;
        }
        case 's': slave = optarg; break;
        case 'k': check = 1; break;
        case 'R': retain = optarg; break;
        case 'W': warm = 1; break;
        case 'C': warm = 0; break;
        case 'P': {
            char *end;
            errno = 0;
            retain_ms = strtoull(optarg, &end, 10);
            if (errno || *end || !*optarg || optarg[0] == '-') {
                fprintf(stderr, "%s: error: --retain-period takes milliseconds\n", argv[0]);
                return 2;
            }
            retain_ms_given = 1;
            break;
        }
        case 'h': usage(stdout, argv[0]); return 0;
        default: usage(stderr, argv[0]); return 2;
        }
    }
    if (optind != argc) { usage(stderr, argv[0]); return 2; }

    char err[512];
    plcrt_t *rt = plcrt_new(plcrt_linked_program(), err, sizeof err);
    if (!rt) { fprintf(stderr, "%s: error: %s\n", argv[0], err); return 2; }
    if (config && plcrt_load_config(rt, config) != 0) {
        fprintf(stderr, "%s\n", plcrt_errmsg(rt));
        plcrt_free(rt);
        return 2;
    }
    /* saved would count snapshots that hold none of the program's state: a program relying
     * on it would show a peer what a restart then forgets */
    if (config && plcrt_retain_handshake(rt) && plcrt_retain_count(rt) == 0) {
        fprintf(stderr, "%s: error: [retain] request/saved: the program has no RETAIN variables "
                        "(or was linked without their table, which plcrt-build generates): "
                        "no snapshot would hold its state\n", config);
        plcrt_free(rt);
        return 2;
    }
    if (check) { plcrt_free(rt); return 0; }
    /* the command line wins over the config's [retain] section */
    char retain_cfg[1024];
    uint64_t retain_period_ns = retain_ms * 1000000ull;
    if (!retain && plcrt_retain_file(rt)) {
        snprintf(retain_cfg, sizeof retain_cfg, "%s", plcrt_retain_file(rt));
        retain = retain_cfg;
        if (!retain_ms_given) retain_period_ns = plcrt_retain_period_ns(rt);
    }
    if (retain) {
        if (plcrt_retain_count(rt) == 0)
            fprintf(stderr, "plcrt: retain: the program has no RETAIN variables (or was linked "
                            "without their table, which plcrt-build generates)\n");
        if (!warm) {
            fprintf(stderr, "plcrt: cold start (--cold)\n");
        } else if (plcrt_retain_load_file(rt, retain) == 1) {
            fprintf(stderr, "plcrt: warm start: %zu retained variables restored from %s\n",
                    plcrt_retain_count(rt), retain);
        } else if (plcrt_errmsg(rt)[0]) {
            fprintf(stderr, "plcrt: cold start: %s\n", plcrt_errmsg(rt));
        } else {
            fprintf(stderr, "plcrt: cold start: no retain file %s yet\n", retain);
        }
        plcrt_retain_set_file(rt, retain, retain_period_ns);
    }
    if (slave) {
        char host[256] = "127.0.0.1";
        const char *colon = strrchr(slave, ':');
        const char *port_s = slave;
        if (colon) {
            size_t n = (size_t)(colon - slave);
            if (n >= sizeof host) n = sizeof host - 1;
            memcpy(host, slave, n);
            host[n] = 0;
            port_s = colon + 1;
        }
        char *end;
        long port = strtol(port_s, &end, 10);
        if (*end || port < 0 || port > 65535) {
            fprintf(stderr, "%s: error: -s takes [HOST:]PORT\n", argv[0]);
            return 2;
        }
        if (plcrt_slave_start(rt, host, (int)port) != 0) {
            fprintf(stderr, "%s: error: %s\n", argv[0], plcrt_errmsg(rt));
            return 1;
        }
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    int rc;
    if (realtime) {
        rc = plcrt_run_realtime(rt, scans, &stop_requested);
        plcrt_rt_stats_t st;
        plcrt_rt_stats(rt, &st);
        fprintf(stderr, "plcrt: real-time: %llu scans of %.3f ms, %llu overruns, max late %.3f ms, max scan %.3f ms\n",
                (unsigned long long)st.scans, plcrt_tick_ns(rt) / 1e6, (unsigned long long)st.overruns,
                st.max_late_ns / 1e6, st.max_scan_ns / 1e6);
    } else {
        if (!scans_given) scans = 1000;
        rc = 0;
        for (unsigned long long i = 0; i < scans && !stop_requested && rc == 0; i++)
            rc = plcrt_scan(rt, 1);
        if (rc == 0) rc = plcrt_flush_outputs(rt);
        fprintf(stderr, "plcrt: virtual: %llu scans, virtual time %.3f s\n",
                (unsigned long long)plcrt_scan_count(rt), plcrt_time_ns(rt) / 1e9);
    }
    if (rc != 0) fprintf(stderr, "%s: error: %s\n", argv[0], plcrt_errmsg(rt));
    if (retain && plcrt_retain_stop(rt) != 0) {
        fprintf(stderr, "plcrt: %s\n", plcrt_errmsg(rt));
        rc = rc ? rc : 1;
    }
    plcrt_free(rt);
    return rc ? 1 : 0;
}
