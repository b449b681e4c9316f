/* mip-emulator: Modbus TCP front of the mipemu core, driven in real time by the monotonic clock.
 * One listening port for the MDP-810, one per TRM-810. epoll, non-blocking sockets; the core
 * answers every frame, this file only moves bytes. */
#define _GNU_SOURCE
#include "cli_config.h"
#include "mipemu.h"
#include "rtu.h"
#include "siprotec.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <inttypes.h>
#include <limits.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define PROG "mip-emulator"
#define OUT_HIGH_WATER (64 * 1024) /* stop reading a client that does not read its answers */

static const char USAGE[] =
    "usage: " PROG " [options]\n"
    "Emulates a Piciorgros MIP radio network: one MDP-810 central and N TRM-810 outstations,\n"
    "each a Modbus TCP server. Runs until SIGINT or SIGTERM.\n"
    "\n"
    "  --host ADDR            address to listen on (default 127.0.0.1)\n"
    "  --mdp-port PORT        MDP-810 port; the Modbus unit id selects the station (default 15020;\n"
    "                         0 = any free port)\n"
    "  --trm-base-port PORT   TRM-810 of station s listens on PORT+s-1 (default 15021;\n"
    "                         0 = a free port each)\n"
    "  --stations N           number of outstations, addresses 1..N (1..247, default 1)\n"
    "  --mode MODE            dynamic (default) or static transfer\n"
    "  --static-registers N   static mode: registers mirrored per direction (1..148, default 148)\n"
    "  --loss-down P          probability a MDP->station telegram is lost (0..1, default 0)\n"
    "  --loss-up P            probability a station->MDP telegram is lost (0..1, default 0)\n"
    "  --burst L              bursty loss (Gilbert-Elliott), mean burst length L telegrams (>= 1;\n"
    "                         default 0 = independent losses)\n"
    "  --seed S               seed of the radio randomness (default 1)\n"
    "  --bitrate B            radio bit rate in bit/s (300..10000000, default 9600)\n"
    "  --slot-gap-ms MS       turnaround gap after every telegram in ms (default 20)\n"
    "  --overhead-bytes N     bytes per telegram besides the registers (1..255, default 12)\n"
    "  --fail-polls N         unanswered polls before a station counts as not reachable (default 3)\n"
    "  --allow-127            accept up to 127 registers per request, as the device does\n"
    "                         (default: the Modbus limits 125 read / 123 FC16 / 121 FC23 write)\n"
    "                         (not with --rtu: an RTU frame holds at most 256 bytes)\n"
    "  --lose-record N        lose the first uplink block whose register 0 is N, once per\n"
    "                         station (the note's example: --lose-record 2); default off\n"
    "  --relay PORT[:KEY=VALUE,...]\n"
    "                         also a SIPROTEC event recorder (Modbus TCP) on PORT (0 = any);\n"
    "                         keys: base, cap, overflow=drop-oldest|drop-new, seq-bits,\n"
    "                         bad-ack=exc03|ignore, rate (events/s), burst=N/SECONDS,\n"
    "                         origin (ms since 1970 of time 0; default: now), script=FILE\n"
    "  --rtu PORT[:BAUD[:FRAME]]=DEVICES\n"
    "                         also serve endpoints as Modbus RTU slaves on a serial line: PORT is\n"
    "                         'pty' (a new pty), 'pty:LINK' (and a symlink LINK to it) or a tty;\n"
    "                         BAUD a tty rate (300 .. 4000000), default 19200; FRAME 8 data bits,\n"
    "                         parity N/E/O, stop bits 1/2, default 8N1 (8E1, 8O1, 8N2, ...);\n"
    "                         DEVICES: 'mdp' (unit id = station) and/or 'trmS@UNIT' (the TRM-810\n"
    "                         of station S at unit id UNIT), comma-separated; may be repeated\n"
    "  --no-tcp               serve no TCP ports (RTU only)\n"
    "  --trace FILE           write the JSON-lines trace to FILE ('-' = stdout)\n"
    "  --help                 this text\n"
    "\n"
    "When all ports are bound it prints one line:\n"
    "  mip-emulator: listening mdp=HOST:PORT trm=PORT1,PORT2,... [rtu=TTY1,TTY2,...] [relay=PORT]\n"
    "(with --no-tcp: mdp=none trm=none). Serial lines: docs/serial.md.\n"
    "Register maps, status bits, radio timing and trace format: emulator/README.md.\n";

__attribute__((noreturn)) static void die_sys(const char *what)
{
    fprintf(stderr, PROG ": error: %s: %s\n", what, strerror(errno));
    exit(1);
}

/* ---- connections ---- */

enum { T_LISTEN, T_CONN, T_RTU, T_RTU_WATCH };

#define MAX_BUSES 8
typedef struct bus_slot {
    int type; /* T_RTU: shares the first member with conn_t for the epoll tag */
    rtu_bus bus;
} bus_slot_t;
static bus_slot_t g_buses[MAX_BUSES];
static int g_nbus;
typedef struct watch_slot {
    int type; /* T_RTU_WATCH: a client closed a pty (rtu_on_watch) */
    rtu_bus *bus;
} watch_slot_t;
static watch_slot_t g_watches[MAX_BUSES];

typedef struct conn {
    int type;
    int fd;
    int ep;                       /* endpoint of the core */
    uint8_t in[2 * MIPEMU_FRAME_MAX];
    size_t in_len;
    uint8_t *out;
    size_t out_len, out_off, out_cap;
    uint32_t events;
    int eof;                      /* the client shut down its side: drain the answers, close */
    struct conn *prev, *next;     /* open connections, freed at exit */
} conn_t;

static conn_t *g_conns;
static int g_spare_fd = -1;       /* kept in reserve to shed clients when descriptors run out */

static volatile sig_atomic_t g_stop;
static void on_signal(int sig) { (void)sig; g_stop = 1; }

static int g_epfd;
static mipemu_net *g_net;
static uint64_t g_t0;
static FILE *g_trace;
static long g_clients;

/* --relay: one SIPROTEC event recorder on its own port (endpoint EP_RELAY) */
#define EP_RELAY (-1)
static siprotec_relay *g_relay;
static uint16_t g_relay_base;

/* The relay's part of the SOE_Control handshake in the trace (docs/view.md follows it): a read
 * that shows SOE_Control while entries are offered, and every write to SOE_Control (the
 * acknowledgement), each as one small "relay" line at the core's clock, which is the relay's. */
static void relay_trace(const uint8_t *req, size_t len, const uint8_t *resp, long rl,
                        const siprotec_stats *before)
{
    if (!g_trace || len < 12 || rl < 9)
        return;
    unsigned fc = req[7], a = (unsigned)(req[8] << 8 | req[9]), q = (unsigned)(req[10] << 8 | req[11]);
    unsigned ctl = (unsigned)g_relay_base + 1, exc = resp[7] & 0x80 ? resp[8] : 0;
    siprotec_stats st;
    siprotec_get_stats(g_relay, &st);
    char f[200];
    if (fc == 3 && !exc && a <= ctl && a + q > ctl && st.offered > 0) {
        uint16_t soe;
        siprotec_peek(g_relay, (uint16_t)ctl, 1, &soe);
        snprintf(f, sizeof f, "\"ev\":\"relay\",\"fc\":3,\"ra\":%u,\"rq\":%u,\"soe\":%u,\"offered\":%u,"
                 "\"entries\":%u", a, q, soe, st.offered, st.entries);
    } else if ((fc == 6 || (fc == 16 && len >= 15)) && a == ctl) {
        unsigned v = fc == 6 ? (unsigned)(req[10] << 8 | req[11]) : (unsigned)(req[13] << 8 | req[14]);
        snprintf(f, sizeof f, "\"ev\":\"relay\",\"fc\":%u,\"wa\":%u,\"w0\":%u,\"exc\":%u,\"acked\":%llu,"
                 "\"entries\":%u", fc, a, v, exc,
                 (unsigned long long)(st.acknowledged - before->acknowledged), st.entries);
    } else {
        return;
    }
    mipemu_net_trace_note(g_net, f);
}

static uint64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ULL + (uint64_t)ts.tv_nsec;
}

/* epoll_wait with a timeout in ns: epoll_pwait2 (Linux 5.11); before it, whole ms rounded up */
static int epoll_wait_ns(int epfd, struct epoll_event *evs, int max, uint64_t ns)
{
    static int no_pwait2;
    if (!no_pwait2) {
        struct timespec ts = { .tv_sec = (time_t)(ns / 1000000000ull), .tv_nsec = (long)(ns % 1000000000ull) };
        int n = epoll_pwait2(epfd, evs, max, &ts, NULL);
        if (n >= 0 || errno != ENOSYS)
            return n;
        no_pwait2 = 1;
    }
    return epoll_wait(epfd, evs, max, (int)((ns + 999999) / 1000000));
}

static void advance_now(void) { mipemu_net_advance(g_net, mono_ns() - g_t0); }

/* a frame from a serial line: the core answers it as it answers TCP (same trace) */
static long rtu_handle(void *user, int ep, uint64_t at_ns, const uint8_t *req, size_t len,
                       uint8_t *resp, size_t cap)
{
    (void)user;
    (void)at_ns; /* the core already stands at the clock's now, a gap after the frame ended */
    if (cap < MIPEMU_RESPONSE_MAX)
        return -1;
    return mipemu_handle(g_net, ep, req, len, resp, cap);
}

static void trace_to_file(void *user, const char *line, size_t len)
{
    fwrite(line, 1, len, (FILE *)user);
}

static void conn_close(conn_t *c)
{
    if (c->prev)
        c->prev->next = c->next;
    else
        g_conns = c->next;
    if (c->next)
        c->next->prev = c->prev;
    epoll_ctl(g_epfd, EPOLL_CTL_DEL, c->fd, NULL);
    close(c->fd);
    free(c->out);
    free(c);
    g_clients--;
}

static void set_events(conn_t *c, uint32_t ev)
{
    if (c->events == ev)
        return;
    struct epoll_event e = { .events = ev, .data.ptr = c };
    epoll_ctl(g_epfd, EPOLL_CTL_MOD, c->fd, &e);
    c->events = ev;
}

/* returns -1 when the connection has to go */
static int flush_out(conn_t *c)
{
    while (c->out_off < c->out_len) {
        ssize_t n = send(c->fd, c->out + c->out_off, c->out_len - c->out_off, MSG_NOSIGNAL);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                break;
            return -1;
        }
        c->out_off += (size_t)n;
    }
    if (c->out_off == c->out_len)
        c->out_off = c->out_len = 0;
    return 0;
}

static int append_out(conn_t *c, const uint8_t *b, size_t n)
{
    if (c->out_len + n > c->out_cap) {
        if (c->out_off) {
            memmove(c->out, c->out + c->out_off, c->out_len - c->out_off);
            c->out_len -= c->out_off;
            c->out_off = 0;
        }
        if (c->out_len + n > c->out_cap) {
            size_t cap = (c->out_len + n) * 2;
            uint8_t *p = realloc(c->out, cap);
            if (!p)
                return -1;
            c->out = p;
            c->out_cap = cap;
        }
    }
    memcpy(c->out + c->out_len, b, n);
    c->out_len += n;
    return 0;
}

/* Answers every whole frame in the input buffer; -1 closes the connection. */
static int process_frames(conn_t *c)
{
    size_t off = 0;
    int advanced = 0;
    while (off < c->in_len) {
        long fl = mipemu_frame_length(c->in + off, c->in_len - off);
        if (c->ep == EP_RELAY) {
            if (fl < 0)
                return -1;
            if (fl == 0 || (size_t)fl > c->in_len - off)
                break;
            uint8_t resp[SIPROTEC_RESPONSE_MAX];
            siprotec_advance(g_relay, mono_ns() - g_t0);
            siprotec_stats before;
            siprotec_get_stats(g_relay, &before);
            long rl = siprotec_handle(g_relay, c->in + off, (size_t)fl, resp, sizeof resp);
            if (rl < 0 || append_out(c, resp, (size_t)rl) < 0)
                return -1;
            if (g_trace) {
                advance_now(); /* the line's time: the relay's now on the same clock */
                relay_trace(c->in + off, (size_t)fl, resp, rl, &before);
            }
            off += (size_t)fl;
            continue;
        }
        if (fl < 0) {
            /* let the core see (and trace) the bad frame; it answers "close" */
            uint8_t resp[MIPEMU_RESPONSE_MAX];
            advance_now();
            mipemu_handle(g_net, c->ep, c->in + off, c->in_len - off, resp, sizeof resp);
            return -1;
        }
        if (fl == 0 || (size_t)fl > c->in_len - off)
            break;
        if (!advanced) {
            advance_now();
            advanced = 1;
        }
        uint8_t resp[MIPEMU_RESPONSE_MAX];
        long rl = mipemu_handle(g_net, c->ep, c->in + off, (size_t)fl, resp, sizeof resp);
        if (rl < 0 || append_out(c, resp, (size_t)rl) < 0)
            return -1;
        off += (size_t)fl;
    }
    if (off) {
        memmove(c->in, c->in + off, c->in_len - off);
        c->in_len -= off;
    }
    return 0;
}

static void on_readable(conn_t *c)
{
    for (;;) {
        if (c->out_len - c->out_off > OUT_HIGH_WATER)
            break; /* the client does not read: wait until it does */
        ssize_t n = recv(c->fd, c->in + c->in_len, sizeof c->in - c->in_len, 0);
        if (n == 0) {
            /* the client finished sending: answers to what it sent still go out, then close */
            if (flush_out(c) < 0 || c->out_len == c->out_off) {
                conn_close(c);
                return;
            }
            c->eof = 1;
            set_events(c, EPOLLOUT);
            return;
        }
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                break;
            conn_close(c);
            return;
        }
        c->in_len += (size_t)n;
        if (process_frames(c) < 0) {
            flush_out(c); /* answers to the frames before the bad one still go out */
            conn_close(c);
            return;
        }
    }
    if (flush_out(c) < 0) {
        conn_close(c);
        return;
    }
    int pending = c->out_len > c->out_off;
    int reading = c->out_len - c->out_off <= OUT_HIGH_WATER;
    set_events(c, (reading ? EPOLLIN : 0) | (pending ? EPOLLOUT : 0));
}

static void on_writable(conn_t *c)
{
    if (flush_out(c) < 0 || (c->eof && c->out_len == c->out_off)) {
        conn_close(c);
        return;
    }
    if (c->eof)
        return;
    if (c->out_len - c->out_off <= OUT_HIGH_WATER) {
        set_events(c, EPOLLIN | (c->out_len > c->out_off ? EPOLLOUT : 0));
        on_readable(c); /* data may be waiting that we stopped reading */
    }
}

static void on_accept(conn_t *l)
{
    for (;;) {
        int fd = accept4(l->fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR || errno == ECONNABORTED)
                continue;
            if ((errno == EMFILE || errno == ENFILE) && g_spare_fd >= 0) {
                /* out of descriptors: shed this client instead of spinning on a readable listener */
                static int warned;
                if (!warned) {
                    warned = 1;
                    fprintf(stderr, PROG ": warning: out of file descriptors, refusing clients\n");
                }
                close(g_spare_fd);
                int fd2 = accept(l->fd, NULL, NULL);
                if (fd2 >= 0)
                    close(fd2);
                g_spare_fd = open("/dev/null", O_RDONLY | O_CLOEXEC);
                if (fd2 >= 0)
                    continue;
                /* EMFILE comes before "nothing queued": stop when the queue is empty */
            }
            return;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        conn_t *c = calloc(1, sizeof *c);
        if (!c) {
            close(fd);
            continue;
        }
        c->type = T_CONN;
        c->fd = fd;
        c->ep = l->ep;
        c->events = EPOLLIN;
        struct epoll_event e = { .events = EPOLLIN, .data.ptr = c };
        if (epoll_ctl(g_epfd, EPOLL_CTL_ADD, fd, &e) < 0) {
            close(fd);
            free(c);
            continue;
        }
        c->next = g_conns;
        if (g_conns)
            g_conns->prev = c;
        g_conns = c;
        g_clients++;
    }
}

static int listen_on(const char *host, int port, int *bound_port)
{
    struct sockaddr_in a = { .sin_family = AF_INET, .sin_port = htons((uint16_t)port) };
    if (inet_pton(AF_INET, host, &a.sin_addr) != 1)
        cli_usage_error("--host expects an IPv4 address, got '%s'", host);
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0)
        die_sys("socket");
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, (struct sockaddr *)&a, sizeof a) < 0) {
        fprintf(stderr, PROG ": error: cannot listen on %s:%d: %s\n", host, port, strerror(errno));
        exit(1);
    }
    if (listen(fd, 512) < 0)
        die_sys("listen");
    socklen_t len = sizeof a;
    getsockname(fd, (struct sockaddr *)&a, &len);
    *bound_port = ntohs(a.sin_port);
    return fd;
}

/* The value v of the --relay key: 0 for a, 1 for b, else a usage error that names both. */
static int relay_choice(const char *key, const char *v, const char *a, const char *b)
{
    if (!strcmp(v, a))
        return 0;
    if (!strcmp(v, b))
        return 1;
    cli_usage_error("--relay %s: '%s' is not %s or %s", key, v, a, b);
}

/* Script file of --relay: one event a line, "SECONDS W0 W1 W2 W3" (time since start; register
 * type / bit offset, address, cause / type, value; decimal or 0x..); '#' starts a comment. */
static void relay_load_script(siprotec_relay *r, const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f)
        cli_usage_error("--relay script=%s: %s", path, strerror(errno));
    char line[512];
    int ln = 0;
    while (cli_script_line(f, line, sizeof line, &ln)) {
        char *p = line, *e;
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p == '\n' || *p == 0)
            continue;
        double t = strtod(p, &e);
        if (e == p || !(t >= 0 && t <= 1e9))
            cli_usage_error("%s:%d: a time in seconds (0..1e9) first", path, ln);
        uint16_t w[4];
        for (int i = 0; i < 4; i++) {
            p = e;
            long v = strtol(p, &e, 0);
            if (e == p || v < 0 || v > 65535)
                cli_usage_error("%s:%d: four register values 0..65535 after the time", path, ln);
            w[i] = (uint16_t)v;
        }
        while (*e == ' ' || *e == '\t' || *e == '\r')
            e++;
        if (*e != '\n' && *e != 0)
            cli_usage_error("%s:%d: unexpected '%.20s'", path, ln, e);
        if (siprotec_script(r, (uint64_t)(t * 1e9 + 0.5), w) < 0)
            cli_usage_error("%s:%d: out of memory", path, ln);
    }
    fclose(f);
}

/* --relay PORT[:KEY=VALUE,...] */
static siprotec_relay *relay_parse(const char *spec, int *port)
{
    siprotec_config c;
    siprotec_config_default(&c);
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts); /* the front may read the wall clock; the core never does */
    c.time_origin_ms = (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
    char buf[1024];
    if (strlen(spec) >= sizeof buf)
        cli_usage_error("--relay: too long");
    strcpy(buf, spec);
    char *opts = strchr(buf, ':');
    if (opts)
        *opts++ = 0;
    *port = (int)cli_long("--relay", buf, 0, 65535);
    const char *script = NULL;
    for (char *kv = opts ? strtok(opts, ",") : NULL; kv; kv = strtok(NULL, ",")) {
        char *v = strchr(kv, '=');
        if (!v)
            cli_usage_error("--relay: '%s' is not KEY=VALUE", kv);
        *v++ = 0;
        if (!strcmp(kv, "base"))
            c.base = (uint16_t)cli_long("--relay base", v, 0, 65535 - SIPROTEC_MAP_REGS + 1);
        else if (!strcmp(kv, "cap"))
            c.capacity = (uint32_t)cli_long("--relay cap", v, SIPROTEC_BLOCKS, 1000000);
        else if (!strcmp(kv, "overflow"))
            c.overflow = relay_choice(kv, v, "drop-oldest", "drop-new") ? SIPROTEC_OVF_DROP_NEW
                                                                        : SIPROTEC_OVF_DROP_OLDEST;
        else if (!strcmp(kv, "seq-bits"))
            c.seq_bits = (int)cli_long("--relay seq-bits", v, 2, 8);
        else if (!strcmp(kv, "bad-ack"))
            c.bad_ack = relay_choice(kv, v, "exc03", "ignore") ? SIPROTEC_BAD_ACK_IGNORE
                                                               : SIPROTEC_BAD_ACK_EXC03;
        else if (!strcmp(kv, "rate"))
            c.rate = cli_double("--relay rate", v, 0, 1e6);
        else if (!strcmp(kv, "burst")) {
            char *sl = strchr(v, '/');
            if (!sl)
                cli_usage_error("--relay burst: '%s' is not N/SECONDS", v);
            *sl++ = 0;
            c.burst_n = (uint32_t)cli_long("--relay burst", v, 0, 1000000);
            c.burst_every_s = cli_double("--relay burst period", sl, 0.001, 1e6);
        } else if (!strcmp(kv, "origin"))
            c.time_origin_ms = (uint64_t)cli_double("--relay origin", v, 0, 9e15);
        else if (!strcmp(kv, "script"))
            script = v;
        else
            cli_usage_error("--relay: unknown key '%s'", kv);
    }
    char err[160];
    siprotec_relay *r = siprotec_new(&c, err, sizeof err);
    if (!r)
        cli_usage_error("--relay: %s", err);
    if (script)
        relay_load_script(r, script);
    g_relay_base = c.base;
    return r;
}

int main(int argc, char **argv)
{
    cli_prog = PROG;
    mipemu_config cfg;
    mipemu_config_default(&cfg);
    const char *host = "127.0.0.1";
    const char *trace_path = NULL;
    int mdp_port = 15020, trm_base = 15021;

    /* own options, then the network options of cli_config.c (long index >= N_OWN) */
    enum { O_HOST = 256, O_MDP, O_TRM, O_TRACE, O_HELP, O_RTU, O_NOTCP, O_RELAY, O_NET };
    const char *relay_spec = NULL;
    const char *rtu_specs[MAX_BUSES];
    int n_rtu = 0, no_tcp = 0;
    static const struct option own[] = {
        { "host", required_argument, 0, O_HOST },
        { "mdp-port", required_argument, 0, O_MDP },
        { "trm-base-port", required_argument, 0, O_TRM },
        { "trace", required_argument, 0, O_TRACE },
        { "help", no_argument, 0, O_HELP },
        { "rtu", required_argument, 0, O_RTU },
        { "no-tcp", no_argument, 0, O_NOTCP },
        { "relay", required_argument, 0, O_RELAY },
    };
    enum { N_OWN = sizeof own / sizeof own[0] };
    struct option opts[N_OWN + 32];
    memcpy(opts, own, sizeof own);
    for (int i = 0; i < cli_net_option_count; i++)
        opts[N_OWN + i] = (struct option){ cli_net_options[i].name,
                                           cli_net_options[i].has_value ? required_argument
                                                                        : no_argument,
                                           0, O_NET };
    opts[N_OWN + cli_net_option_count] = (struct option){ 0, 0, 0, 0 };
    opterr = 0;
    int o, idx;
    while ((o = getopt_long(argc, argv, ":", opts, &idx)) != -1) {
        switch (o) {
        case O_HOST: host = optarg; break;
        case O_MDP: mdp_port = (int)cli_long("--mdp-port", optarg, 0, 65535); break;
        case O_TRM: trm_base = (int)cli_long("--trm-base-port", optarg, 0, 65535); break;
        case O_TRACE: trace_path = optarg; break;
        case O_HELP: fputs(USAGE, stdout); return 0;
        case O_NET: cli_net_option_apply(&cfg, idx - N_OWN, optarg); break;
        case O_RTU:
            if (n_rtu == MAX_BUSES)
                cli_usage_error("more than %d --rtu lines", MAX_BUSES);
            rtu_specs[n_rtu++] = optarg;
            break;
        case O_NOTCP: no_tcp = 1; break;
        case O_RELAY:
            if (relay_spec)
                cli_usage_error("--relay given twice");
            relay_spec = optarg;
            break;
        case ':': cli_usage_error("option %s needs a value", argv[optind - 1]);
        default:
            cli_usage_error("unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind < argc)
        cli_usage_error("unexpected argument '%s'", argv[optind]);
    if (trm_base != 0 && trm_base + cfg.stations - 1 > 65535)
        cli_usage_error("--trm-base-port %d leaves no room for %d stations", trm_base, cfg.stations);

    char err[160];
    g_net = mipemu_net_new(&cfg, err, sizeof err);
    if (!g_net)
        cli_usage_error("%s", err);

    if (no_tcp && n_rtu == 0)
        cli_usage_error("--no-tcp needs at least one --rtu line");
    int relay_port = 0, relay_bound = 0;
    if (relay_spec)
        g_relay = relay_parse(relay_spec, &relay_port);
    cli_rtu_allow_127_check(&cfg, n_rtu);
    for (int i = 0; i < n_rtu; i++) {
        if (rtu_parse(&g_buses[i].bus, rtu_specs[i], cfg.stations, err, sizeof err) < 0)
            cli_usage_error("%s", err);
        cli_rtu_line_check(rtu_specs[i], g_buses[i].bus.baud, g_buses[i].bus.data_bits,
                           g_buses[i].bus.parity, g_buses[i].bus.stop_bits);
        g_buses[i].type = T_RTU;
        for (int j = 0; j < i; j++)
            if (g_buses[j].bus.link[0] && !strcmp(g_buses[j].bus.link, g_buses[i].bus.link))
                cli_usage_error("--rtu '%s': the link %s is already used", rtu_specs[i], g_buses[i].bus.link);
    }

    if (trace_path) {
        g_trace = strcmp(trace_path, "-") ? fopen(trace_path, "w") : stdout;
        if (!g_trace) {
            fprintf(stderr, PROG ": error: cannot write trace %s: %s\n", trace_path, strerror(errno));
            return 1;
        }
        mipemu_net_set_trace(g_net, trace_to_file, g_trace);
    }

    /* many clients: lift the descriptor limit as far as allowed (epoll has no FD_SETSIZE) */
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < rl.rlim_max) {
        rl.rlim_cur = rl.rlim_max;
        setrlimit(RLIMIT_NOFILE, &rl);
    }
    struct sigaction sa = { .sa_handler = on_signal };
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    g_spare_fd = open("/dev/null", O_RDONLY | O_CLOEXEC);
    g_epfd = epoll_create1(EPOLL_CLOEXEC);
    if (g_epfd < 0)
        die_sys("epoll_create1");
    int nlisten = no_tcp ? 0 : cfg.stations + 1;
    conn_t *listeners = calloc((size_t)nlisten, sizeof *listeners);
    int *ports = calloc((size_t)nlisten, sizeof *ports);
    if (!listeners || !ports)
        die_sys("calloc");
    for (int i = 0; i < nlisten; i++) {
        int want = i == 0 ? mdp_port : trm_base == 0 ? 0 : trm_base + i - 1;
        listeners[i].type = T_LISTEN;
        listeners[i].ep = i;
        listeners[i].fd = listen_on(host, want, &ports[i]);
        struct epoll_event e = { .events = EPOLLIN, .data.ptr = &listeners[i] };
        if (epoll_ctl(g_epfd, EPOLL_CTL_ADD, listeners[i].fd, &e) < 0)
            die_sys("epoll_ctl");
    }
    conn_t relay_listener = { .type = T_LISTEN, .ep = EP_RELAY, .fd = -1 };
    if (g_relay) {
        relay_listener.fd = listen_on(host, relay_port, &relay_bound);
        struct epoll_event e = { .events = EPOLLIN, .data.ptr = &relay_listener };
        if (epoll_ctl(g_epfd, EPOLL_CTL_ADD, relay_listener.fd, &e) < 0)
            die_sys("epoll_ctl");
    }
    for (int i = 0; i < n_rtu; i++) {
        if (rtu_open(&g_buses[i].bus, err, sizeof err) < 0) {
            fprintf(stderr, PROG ": error: %s\n", err);
            for (int j = 0; j < i; j++)
                rtu_close(&g_buses[j].bus);
            return 1;
        }
        struct epoll_event e = { .events = EPOLLIN, .data.ptr = &g_buses[i] };
        if (epoll_ctl(g_epfd, EPOLL_CTL_ADD, g_buses[i].bus.fd, &e) < 0)
            die_sys("epoll_ctl");
        if (g_buses[i].bus.watch_fd >= 0) {
            g_watches[i] = (watch_slot_t){ T_RTU_WATCH, &g_buses[i].bus };
            struct epoll_event w = { .events = EPOLLIN, .data.ptr = &g_watches[i] };
            if (epoll_ctl(g_epfd, EPOLL_CTL_ADD, g_buses[i].bus.watch_fd, &w) < 0)
                die_sys("epoll_ctl");
        }
        g_nbus++;
    }
    if (no_tcp) {
        printf(PROG ": listening mdp=none trm=none");
    } else {
        printf(PROG ": listening mdp=%s:%d trm=", host, ports[0]);
        for (int i = 1; i < nlisten; i++)
            printf("%s%d", i > 1 ? "," : "", ports[i]);
    }
    for (int i = 0; i < n_rtu; i++)
        printf("%s%s", i ? "," : " rtu=", g_buses[i].bus.path);
    if (g_relay)
        printf(" relay=%d", relay_bound);
    printf("\n");
    fflush(stdout);
    for (int i = 0; i < n_rtu; i++) {
        char note[512];
        if (rtu_parity_note(&g_buses[i].bus, note, sizeof note))
            fprintf(stderr, PROG ": note: %s\n", note);
    }

    g_t0 = mono_ns();
    if (g_relay && g_trace) {
        /* the clock's origin, so a file written by another process with CLOCK_MONOTONIC times
         * (the SCADA stand-in's entries, mippeer.scada --out) lines up with the trace */
        char f[96];
        snprintf(f, sizeof f, "\"ev\":\"relay\",\"start\":true,\"mono_ns\":%llu", (unsigned long long)g_t0);
        mipemu_net_trace_note(g_net, f);
    }
    struct epoll_event evs[256];
    while (!g_stop) {
        uint64_t now = mono_ns() - g_t0;
        uint64_t next = mipemu_net_next_event(g_net);
        for (int i = 0; i < g_nbus; i++) {
            uint64_t d = rtu_next_deadline(&g_buses[i].bus);
            if (d != UINT64_MAX && d - g_t0 < next)
                next = d - g_t0;
        }
        /* to the nanosecond (epoll_pwait2): a frame closes t3.5 after its last character, 1.75 ms
         * above 19,200 baud; a timeout in whole milliseconds closed it up to 1 ms late */
        uint64_t wait_ns = next > now ? next - now : 0;
        if (wait_ns > 1000000000ull)
            wait_ns = 1000000000ull;
        int n = epoll_wait_ns(g_epfd, evs, 256, wait_ns);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            die_sys("epoll_wait");
        }
        advance_now();
        for (int i = 0; i < n; i++) {
            conn_t *c = evs[i].data.ptr;
            if (c->type == T_RTU_WATCH) {
                rtu_on_watch(((watch_slot_t *)evs[i].data.ptr)->bus);
                continue;
            }
            if (c->type == T_RTU) {
                rtu_on_readable(&((bus_slot_t *)evs[i].data.ptr)->bus, mono_ns(), rtu_handle, NULL);
                continue;
            }
            if (c->type == T_LISTEN) {
                on_accept(c);
                continue;
            }
            if (evs[i].events & (EPOLLERR | EPOLLHUP) && !(evs[i].events & EPOLLIN)) {
                conn_close(c);
                continue;
            }
            if (evs[i].events & EPOLLOUT) {
                on_writable(c);
                continue; /* on_writable reads too; c may be gone */
            }
            if (evs[i].events & EPOLLIN)
                on_readable(c);
        }
        for (int i = 0; i < g_nbus; i++) {
            uint64_t t = mono_ns();
            if (rtu_next_deadline(&g_buses[i].bus) <= t) {
                advance_now();
                rtu_on_time(&g_buses[i].bus, t, rtu_handle, NULL);
            }
        }
        if (g_trace)
            fflush(g_trace);
    }
    for (int i = 0; i < g_nbus; i++)
        rtu_close(&g_buses[i].bus);
    while (g_conns)
        conn_close(g_conns);
    for (int i = 0; i < nlisten; i++)
        close(listeners[i].fd);
    free(listeners);
    free(ports);
    if (relay_listener.fd >= 0)
        close(relay_listener.fd);
    siprotec_free(g_relay);
    close(g_epfd);
    if (g_spare_fd >= 0)
        close(g_spare_fd);
    if (g_trace && g_trace != stdout)
        fclose(g_trace);
    else if (g_trace)
        fflush(g_trace);
    mipemu_net_free(g_net);
    return 0;
}
