/* mipcosim: lockstep co-simulation of plcrt soft-PLCs and the mipemu radio network. */
#include "mipcosim.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#define MAX_PLCS 512
#define MAX_CONNS 1024
#define MAX_TAPS 64
#define NAME_MAX_LEN 64
#define MAX_RELAYS 64

typedef struct plc {
    int used;
    mipcosim_scan_fn scan;
    void *rt;                   /* NULL: switched off */
    uint64_t tick_ns;
    uint64_t due_ns;
} plc_t;

typedef struct conn {
    mipcosim *sim;
    int used;
    int plc;
    int ep;
    int fd_plc, fd_emu;
    int relay;                  /* mipcosim_connect_relay: the relay's id; -1: the modem ep */
    char device[NAME_MAX_LEN];
    uint8_t buf[MIPEMU_FRAME_MAX * 2];
    size_t len;
} conn_t;

typedef struct tap {
    int used;
    int plc;
    const uint16_t *seq, *hdr, *data;
    int nhdr, len_index, ndata_max;
    uint16_t last;
    const uint16_t *fields[16]; /* mipcosim_tap_fields: the header's words one by one (hdr NULL) */
} tap_t;

struct mipcosim {
    mipemu_net *net;
    uint64_t now;
    plc_t plcs[MAX_PLCS];
    int nplcs;
    conn_t *conns[MAX_CONNS];
    tap_t taps[MAX_TAPS];
    uint16_t *log;              /* tap entries */
    size_t log_len, log_cap;
    int failed_plc;
    uint64_t requests, scans;
    FILE *trace;
    char err[256];
    siprotec_relay *relays[MAX_RELAYS];
    int nrelays;
};

static int fail(mipcosim *sim, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int fail(mipcosim *sim, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(sim->err, sizeof sim->err, fmt, ap);
    va_end(ap);
    return -1;
}

mipcosim *mipcosim_new(const mipemu_config *cfg, char *err, size_t errlen)
{
    mipcosim *sim = calloc(1, sizeof *sim);
    if (!sim) {
        if (err && errlen) snprintf(err, errlen, "out of memory");
        return NULL;
    }
    sim->net = mipemu_net_new(cfg, err, errlen);
    if (!sim->net) {
        free(sim);
        return NULL;
    }
    sim->failed_plc = -1;
    return sim;
}

mipcosim *mipcosim_new_args(int stations, int mode, int static_registers, double loss_down,
                            double loss_up, double burst, uint64_t seed, uint32_t bitrate,
                            uint64_t slot_gap_ns, int overhead_bytes, char *err, size_t errlen)
{
    mipemu_config c;
    mipemu_config_default(&c);
    c.stations = stations;
    c.mode = mode;
    c.static_registers = static_registers;
    c.loss_down = loss_down;
    c.loss_up = loss_up;
    c.burst = burst;
    c.seed = seed;
    c.bitrate = bitrate;
    c.slot_gap_ns = slot_gap_ns;
    c.overhead_bytes = overhead_bytes;
    return mipcosim_new(&c, err, errlen);
}

static void conn_close(conn_t *c)
{
    if (c->fd_plc >= 0) close(c->fd_plc);
    if (c->fd_emu >= 0) close(c->fd_emu);
    free(c);
}

void mipcosim_free(mipcosim *sim)
{
    if (!sim) return;
    for (int i = 0; i < MAX_CONNS; i++)
        if (sim->conns[i]) conn_close(sim->conns[i]);
    if (sim->trace) fclose(sim->trace);
    for (int i = 0; i < sim->nrelays; i++) siprotec_free(sim->relays[i]);
    mipemu_net_free(sim->net);
    free(sim->log);
    free(sim);
}

const char *mipcosim_errmsg(const mipcosim *sim) { return sim->err; }
mipemu_net *mipcosim_net(mipcosim *sim) { return sim->net; }
uint64_t mipcosim_now(const mipcosim *sim) { return sim->now; }
int mipcosim_failed_plc(const mipcosim *sim) { return sim->failed_plc; }
uint64_t mipcosim_requests(const mipcosim *sim) { return sim->requests; }
uint64_t mipcosim_scans(const mipcosim *sim) { return sim->scans; }

int mipcosim_plc_add(mipcosim *sim, mipcosim_scan_fn scan, void *rt, uint64_t tick_ns)
{
    if (!scan || !rt) return fail(sim, "plc_add: no scan function or instance");
    if (tick_ns == 0) return fail(sim, "plc_add: tick must be > 0");
    if (sim->nplcs == MAX_PLCS) return fail(sim, "more than %d PLCs", MAX_PLCS);
    int id = sim->nplcs++;
    sim->plcs[id] = (plc_t){1, scan, rt, tick_ns, sim->now};
    return id;
}

static void drop_plc_wiring(mipcosim *sim, int id)
{
    for (int i = 0; i < MAX_TAPS; i++)
        if (sim->taps[i].used && sim->taps[i].plc == id) sim->taps[i].used = 0;
    /* the connections stay: the new instance is wired to the same socketpair, like a PLC
     * that reconnects to its modem; whatever half-exchanged bytes are left are dropped */
    for (int i = 0; i < MAX_CONNS; i++) {
        conn_t *c = sim->conns[i];
        if (!c || c->plc != id) continue;
        uint8_t junk[512];
        while (c->fd_plc >= 0 && recv(c->fd_plc, junk, sizeof junk, MSG_DONTWAIT) > 0) {}
        while (c->fd_emu >= 0 && recv(c->fd_emu, junk, sizeof junk, MSG_DONTWAIT) > 0) {}
        c->len = 0;
    }
}

int mipcosim_plc_replace(mipcosim *sim, int id, mipcosim_scan_fn scan, void *rt, uint64_t tick_ns)
{
    if (id < 0 || id >= sim->nplcs) return fail(sim, "plc_replace: no PLC %d", id);
    if (rt && (!scan || tick_ns == 0)) return fail(sim, "plc_replace: no scan function or tick");
    drop_plc_wiring(sim, id);
    plc_t *p = &sim->plcs[id];
    p->rt = rt;
    if (rt) {
        p->scan = scan;
        p->tick_ns = tick_ns;
        p->due_ns = sim->now;
    }
    return 0;
}

/* The runtime sent a request on fd_plc: answer every whole frame waiting on fd_emu. */
static void after_send(void *user)
{
    conn_t *c = user;
    mipcosim *sim = c->sim;
    for (;;) {
        ssize_t n = recv(c->fd_emu, c->buf + c->len, sizeof c->buf - c->len, MSG_DONTWAIT);
        if (n <= 0) break;
        c->len += (size_t)n;
    }
    while (c->len > 0) {
        long flen = mipemu_frame_length(c->buf, c->len);
        if (flen == 0 || (flen > 0 && (size_t)flen > c->len)) return; /* wait for more */
        uint8_t out[MIPEMU_RESPONSE_MAX];
        long n = flen < 0 ? -1 : mipemu_handle(sim->net, c->ep, c->buf, (size_t)flen, out, sizeof out);
        if (n < 0) {
            /* the emulator closes such a connection: the runtime sees no answer (its
             * timeout) and whatever was buffered is gone */
            c->len = 0;
            return;
        }
        sim->requests++;
        size_t off = 0;
        while (off < (size_t)n) {
            ssize_t w = send(c->fd_emu, out + off, (size_t)n - off, MSG_NOSIGNAL);
            if (w <= 0) break;
            off += (size_t)w;
        }
        memmove(c->buf, c->buf + flen, c->len - (size_t)flen);
        c->len -= (size_t)flen;
    }
}

/* A connected pair of stream sockets: AF_UNIX socketpair, or (tcp) a TCP connection over
 * 127.0.0.1 made in this thread (listen on port 0, connect, accept). */
static int stream_pair(int tcp, int sv[2])
{
    if (!tcp) return socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv);
    int l = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (l < 0) return -1;
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t alen = sizeof a;
    int c = -1, one = 1;
    if (bind(l, (struct sockaddr *)&a, sizeof a) != 0 || listen(l, 1) != 0 ||
        getsockname(l, (struct sockaddr *)&a, &alen) != 0)
        goto fail;
    c = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (c < 0 || connect(c, (struct sockaddr *)&a, sizeof a) != 0) goto fail;
    int e = accept(l, NULL, NULL);
    if (e < 0) goto fail;
    setsockopt(c, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    setsockopt(e, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    close(l);
    sv[0] = c;
    sv[1] = e;
    return 0;
fail:
    if (c >= 0) close(c);
    close(l);
    return -1;
}

/* A connect call's PLC, its function (set_fd or set_transport) and device name. */
static int connect_checks(mipcosim *sim, int id, int have_fn, const char *fn, const char *device)
{
    if (id < 0 || id >= sim->nplcs || !sim->plcs[id].rt) return fail(sim, "connect: no PLC %d", id);
    if (!have_fn || !device) return fail(sim, "connect: no %s function or device", fn);
    return 0;
}

static int endpoint_check(mipcosim *sim, const char *what, int ep)
{
    if (ep < 0 || ep > mipemu_net_stations(sim->net))
        return fail(sim, "%s: endpoint %d is not 0 (MDP) or a station 1..%d", what, ep,
                    mipemu_net_stations(sim->net));
    return 0;
}

static conn_t *device_conn(mipcosim *sim, int id, const char *device, int *slot_out);
static int connect_stream(mipcosim *sim, int id, mipcosim_set_fd_fn set_fd, const char *device,
                          int ep, int tcp);

int mipcosim_connect(mipcosim *sim, int id, mipcosim_set_fd_fn set_fd, const char *device, int ep)
{
    return connect_stream(sim, id, set_fd, device, ep, 0);
}

int mipcosim_connect_tcp(mipcosim *sim, int id, mipcosim_set_fd_fn set_fd, const char *device,
                         int ep)
{
    return connect_stream(sim, id, set_fd, device, ep, 1);
}

static int connect_stream(mipcosim *sim, int id, mipcosim_set_fd_fn set_fd, const char *device,
                          int ep, int tcp)
{
    if (connect_checks(sim, id, set_fd != NULL, "set_fd", device) || endpoint_check(sim, "connect", ep))
        return -1;
    int slot;
    conn_t *c = device_conn(sim, id, device, &slot);
    if (!c) return -1;
    if (slot >= 0) {
        /* a new connection: its stream pair (device_conn left the fds at -1) */
        int sv[2];
        if (stream_pair(tcp, sv) != 0) {
            int e = errno;
            sim->conns[slot] = NULL;
            free(c);
            return fail(sim, "%s: %s", tcp ? "TCP over 127.0.0.1" : "socketpair", strerror(e));
        }
        c->fd_plc = sv[0];
        c->fd_emu = sv[1];
    }
    c->ep = ep;
    c->relay = -1;
    if (set_fd(sim->plcs[id].rt, device, c->fd_plc, after_send, c) != 0)
        return fail(sim, "connect: the runtime refused device '%s'", device);
    return 0;
}

/* In-process transport: one request ADU in, the emulator core's response ADU out. */
static long transact(void *user, const uint8_t *req, size_t req_len, uint8_t *rsp, size_t cap)
{
    conn_t *c = user;
    mipcosim *sim = c->sim;
    long flen = mipemu_frame_length(req, req_len);
    if (flen <= 0 || (size_t)flen != req_len) return -1;
    long n = mipemu_handle(sim->net, c->ep, req, req_len, rsp, cap);
    if (n < 0) return -1; /* the emulator would close the connection: no answer */
    sim->requests++;
    return n;
}

/* The connection of PLC id's device: the one it had (*slot = -1), or a new one without fds in
 * sim->conns[*slot] (NULL: the reason is in sim->err). */
static conn_t *device_conn(mipcosim *sim, int id, const char *device, int *slot_out)
{
    *slot_out = -1;
    if (strlen(device) >= NAME_MAX_LEN) {
        fail(sim, "connect: device name too long");
        return NULL;
    }
    conn_t *c = NULL;
    int slot = -1;
    for (int i = 0; i < MAX_CONNS; i++) {
        conn_t *o = sim->conns[i];
        if (o && o->plc == id && !strcmp(o->device, device)) { c = o; break; }
        if (!o && slot < 0) slot = i;
    }
    if (!c) {
        if (slot < 0) {
            fail(sim, "more than %d connections", MAX_CONNS);
            return NULL;
        }
        c = calloc(1, sizeof *c);
        if (!c) {
            fail(sim, "out of memory");
            return NULL;
        }
        c->sim = sim;
        c->plc = id;
        c->fd_plc = c->fd_emu = -1;
        snprintf(c->device, sizeof c->device, "%s", device);
        sim->conns[slot] = c;
        *slot_out = slot;
    }
    return c;
}

int mipcosim_connect_inproc(mipcosim *sim, int id, mipcosim_set_transport_fn set_transport,
                            const char *device, int ep)
{
    if (connect_checks(sim, id, set_transport != NULL, "set_transport", device) ||
        endpoint_check(sim, "connect", ep))
        return -1;
    int slot;
    conn_t *c = device_conn(sim, id, device, &slot);
    if (!c) return -1;
    c->ep = ep;
    c->relay = -1;
    if (set_transport(sim->plcs[id].rt, device, transact, c) != 0)
        return fail(sim, "connect: the runtime refused device '%s'", device);
    return 0;
}

long mipcosim_request(mipcosim *sim, int ep, const uint8_t *req, size_t req_len, uint8_t *rsp,
                      size_t rsp_cap)
{
    if (endpoint_check(sim, "request", ep)) return -1;
    if (!req || !rsp || rsp_cap < MIPEMU_RESPONSE_MAX)
        return fail(sim, "request: no request, or a response buffer under %d bytes",
                    MIPEMU_RESPONSE_MAX);
    long flen = mipemu_frame_length(req, req_len);
    if (flen <= 0 || (size_t)flen != req_len)
        return fail(sim, "request: %zu bytes are not one whole Modbus TCP frame", req_len);
    long n = mipemu_handle(sim->net, ep, req, req_len, rsp, rsp_cap);
    if (n < 0) return fail(sim, "request: the emulator closes the connection (no answer)");
    sim->requests++;
    return n;
}

int mipcosim_tap(mipcosim *sim, int tap, int id, const uint16_t *seq, const uint16_t *hdr,
                 int nhdr, int len_index, const uint16_t *data, int ndata_max)
{
    if (tap < 0 || tap >= MAX_TAPS) return fail(sim, "tap: slot %d outside 0..%d", tap, MAX_TAPS - 1);
    if (id < 0 || id >= sim->nplcs) return fail(sim, "tap: no PLC %d", id);
    if (!seq || (nhdr > 0 && !hdr) || nhdr < 0 || nhdr > 64 || ndata_max < 0 || ndata_max > 4096)
        return fail(sim, "tap: bad addresses or sizes");
    if (len_index >= nhdr) return fail(sim, "tap: len_index %d outside the header", len_index);
    sim->taps[tap] = (tap_t){1, id, seq, hdr, data, nhdr, len_index, ndata_max, *seq, {0}};
    return 0;
}

int mipcosim_tap_fields(mipcosim *sim, int tap, int id, const uint16_t *seq,
                        const uint16_t *const *fields, int nfields, int len_index,
                        const uint16_t *data, int ndata_max)
{
    if (tap < 0 || tap >= MAX_TAPS) return fail(sim, "tap: slot %d outside 0..%d", tap, MAX_TAPS - 1);
    if (id < 0 || id >= sim->nplcs) return fail(sim, "tap: no PLC %d", id);
    if (!seq || nfields < 0 || nfields > 16 || (nfields > 0 && !fields) || ndata_max < 0 ||
        ndata_max > 4096)
        return fail(sim, "tap: bad addresses or sizes");
    if (len_index >= nfields) return fail(sim, "tap: len_index %d outside the fields", len_index);
    for (int i = 0; i < nfields; i++)
        if (!fields[i]) return fail(sim, "tap: field %d has no address", i);
    tap_t t = {1, id, seq, NULL, data, nfields, len_index, ndata_max, *seq, {0}};
    for (int i = 0; i < nfields; i++) t.fields[i] = fields[i];
    sim->taps[tap] = t;
    return 0;
}

void mipcosim_untap(mipcosim *sim, int tap)
{
    if (tap >= 0 && tap < MAX_TAPS) sim->taps[tap].used = 0;
}

static int log_words(mipcosim *sim, size_t n)
{
    if (sim->log_len + n <= sim->log_cap) return 0;
    size_t cap = sim->log_cap ? sim->log_cap * 2 : 4096;
    while (cap < sim->log_len + n) cap *= 2;
    uint16_t *p = realloc(sim->log, cap * sizeof *p);
    if (!p) return fail(sim, "out of memory for the tap log");
    sim->log = p;
    sim->log_cap = cap;
    return 0;
}

static int check_taps(mipcosim *sim, int id)
{
    for (int i = 0; i < MAX_TAPS; i++) {
        tap_t *t = &sim->taps[i];
        if (!t->used || t->plc != id || *t->seq == t->last) continue;
        t->last = *t->seq;
        int nd = 0;
        if (t->data && t->len_index >= 0) {
            nd = t->hdr ? t->hdr[t->len_index] : *t->fields[t->len_index];
            if (nd > t->ndata_max) nd = t->ndata_max;
        }
        size_t n = 3 + (size_t)t->nhdr + (size_t)nd + 1;
        if (log_words(sim, n)) return -1;
        uint16_t *w = sim->log + sim->log_len;
        w[0] = (uint16_t)i;
        w[1] = (uint16_t)id;
        w[2] = (uint16_t)(t->nhdr + nd + 1);
        if (t->hdr)
            memcpy(w + 3, t->hdr, (size_t)t->nhdr * 2);
        else
            for (int k = 0; k < t->nhdr; k++) w[3 + k] = *t->fields[k];
        if (nd) memcpy(w + 3 + t->nhdr, t->data, (size_t)nd * 2);
        w[n - 1] = *t->seq;   /* last: the seq value, so a rolled-back PLC's undone entries can be told */
        sim->log_len += n;
    }
    return 0;
}

size_t mipcosim_tap_read(mipcosim *sim, uint16_t *buf, size_t cap)
{
    size_t off = 0;
    while (off < sim->log_len) {
        size_t n = 3 + sim->log[off + 2];
        if (off + n > cap) break;
        off += n;
    }
    memcpy(buf, sim->log, off * 2);
    memmove(sim->log, sim->log + off, (sim->log_len - off) * 2);
    sim->log_len -= off;
    return off;
}

int mipcosim_run(mipcosim *sim, uint64_t until_ns)
{
    if (until_ns < sim->now) return fail(sim, "run: %llu lies before now (%llu)",
                                         (unsigned long long)until_ns, (unsigned long long)sim->now);
    for (;;) {
        uint64_t t = until_ns;
        for (int i = 0; i < sim->nplcs; i++)
            if (sim->plcs[i].rt && sim->plcs[i].due_ns < t) t = sim->plcs[i].due_ns;
        if (mipemu_net_advance(sim->net, t) != 0) return fail(sim, "emulator refused time %llu", (unsigned long long)t);
        for (int r = 0; r < sim->nrelays; r++) siprotec_advance(sim->relays[r], t);
        sim->now = t;
        if (t >= until_ns) return 0;
        for (int i = 0; i < sim->nplcs; i++) {
            plc_t *p = &sim->plcs[i];
            if (!p->rt || p->due_ns != t) continue;
            if (p->scan(p->rt, 1) != 0) {
                sim->failed_plc = i;
                return fail(sim, "scan of PLC %d failed", i);
            }
            sim->scans++;
            p->due_ns += p->tick_ns;
            if (check_taps(sim, i)) return -1;
        }
    }
}

static void trace_line(void *user, const char *line, size_t len)
{
    fwrite(line, 1, len, (FILE *)user);
}

int mipcosim_trace_file(mipcosim *sim, const char *path)
{
    if (sim->trace) {
        fclose(sim->trace);
        sim->trace = NULL;
    }
    if (!path) {
        mipemu_net_set_trace(sim->net, NULL, NULL);
        return 0;
    }
    sim->trace = fopen(path, "w");
    if (!sim->trace) return fail(sim, "%s: %s", path, strerror(errno));
    mipemu_net_set_trace(sim->net, trace_line, sim->trace);
    return 0;
}

/* ---- SIPROTEC relays (issue 35) ---- */

int mipcosim_relay_add(mipcosim *sim, const siprotec_config *cfg)
{
    if (!cfg) return fail(sim, "relay_add: no configuration");
    if (sim->nrelays == MAX_RELAYS) return fail(sim, "more than %d relays", MAX_RELAYS);
    char err[200];
    siprotec_relay *r = siprotec_new(cfg, err, sizeof err);
    if (!r) return fail(sim, "relay: %s", err);
    siprotec_advance(r, sim->now);
    sim->relays[sim->nrelays] = r;
    return sim->nrelays++;
}

int mipcosim_relay_restart(mipcosim *sim, int rid, const siprotec_config *cfg)
{
    if (rid < 0 || rid >= sim->nrelays) return fail(sim, "relay_restart: no relay %d", rid);
    if (!cfg) return fail(sim, "relay_restart: no configuration");
    char err[200];
    siprotec_relay *r = siprotec_new(cfg, err, sizeof err);
    if (!r) return fail(sim, "relay: %s", err);
    siprotec_advance(r, sim->now);
    siprotec_free(sim->relays[rid]);
    sim->relays[rid] = r; /* the connections look the relay up by rid at each request */
    return 0;
}

siprotec_relay *mipcosim_relay(mipcosim *sim, int rid)
{
    return rid >= 0 && rid < sim->nrelays ? sim->relays[rid] : NULL;
}

long mipcosim_relay_request(mipcosim *sim, int rid, const uint8_t *req, size_t req_len,
                            uint8_t *rsp, size_t rsp_cap)
{
    siprotec_relay *r = mipcosim_relay(sim, rid);
    if (!r) return fail(sim, "relay request: no relay %d", rid);
    if (!req || !rsp || rsp_cap < SIPROTEC_RESPONSE_MAX)
        return fail(sim, "relay request: no request, or a response buffer under %d bytes",
                    SIPROTEC_RESPONSE_MAX);
    siprotec_advance(r, sim->now);
    long n = siprotec_handle(r, req, req_len, rsp, rsp_cap);
    if (n < 0) return fail(sim, "relay request: not one whole Modbus TCP frame");
    sim->requests++;
    return n;
}

static long transact_relay(void *user, const uint8_t *req, size_t req_len, uint8_t *rsp,
                           size_t cap)
{
    conn_t *c = user;
    mipcosim *sim = c->sim;
    siprotec_relay *r = mipcosim_relay(sim, c->relay);
    if (!r) return -1;
    siprotec_advance(r, sim->now);
    long n = siprotec_handle(r, req, req_len, rsp, cap);
    if (n < 0) return -1; /* malformed: the relay closes the connection */
    sim->requests++;
    return n;
}

int mipcosim_connect_relay(mipcosim *sim, int id, mipcosim_set_transport_fn set_transport,
                           const char *device, int rid)
{
    if (connect_checks(sim, id, set_transport != NULL, "set_transport", device)) return -1;
    if (!mipcosim_relay(sim, rid)) return fail(sim, "connect: no relay %d", rid);
    int slot;
    conn_t *c = device_conn(sim, id, device, &slot);
    if (!c) return -1;
    c->ep = -1;
    c->relay = rid;
    if (set_transport(sim->plcs[id].rt, device, transact_relay, c) != 0)
        return fail(sim, "connect: the runtime refused device '%s'", device);
    return 0;
}
