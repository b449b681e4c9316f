/* Modbus TCP slave exposing the image like OpenPLC: holding registers 0-1023 = %QW,
 * 1024-2047 = %MW, input registers = %IW, coils = %QX, discrete inputs = %IX (bit
 * n = %IX n/8.n%8). Virtual mode serves requests in each scan's I/O phase; real-time
 * mode in a thread.
 *
 * One poll() loop over non-blocking sockets with a buffer per connection: the MBAP framing
 * is parsed here, so a slow, silent or malformed client costs only its own connection.
 * A complete request is decoded without the image lock; the lock is taken only to copy
 * the registers in or out; the reply is sent after it is released. Each pass reads at most
 * one request per connection, so a client pipelining requests cannot starve the others.
 * Timeouts per connection: idle (no byte for idle_timeout while no request is under way)
 * and inter-byte (a started request stalls for byte_timeout). When all slots are taken, a
 * new connection replaces the one that has been quiet longest. */
#define _GNU_SOURCE /* accept4 */
#include "plcrt_internal.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define NBITS (PLCRT_IMAGE_SIZE * 8)
#define MBAP 7          /* transaction id, protocol id, length, unit id */
#define MAX_ADU 260     /* MBAP + 253 bytes of PDU */

typedef struct conn {
    int fd;
    uint8_t in[MAX_ADU];
    size_t in_len;
    uint8_t out[MAX_ADU];
    size_t out_len, out_off;
    uint64_t last_ns; /* last byte received or sent */
} conn_t;

struct plcrt_slave {
    int listen_fd;
    int port;
    conn_t conns[PLCRT_SLAVE_MAX_CLIENTS];
    int n_conns;
    uint64_t idle_ns, byte_ns;
    plcrt_slave_stats_t st;
    pthread_mutex_t st_lock; /* stats are read by other threads */
    pthread_t thread;
    int thread_running;
    volatile int stop;
};

void plcrt_slave_free(struct plcrt_slave *s)
{
    if (!s) return;
    for (int i = 0; i < s->n_conns; i++) close(s->conns[i].fd);
    if (s->listen_fd >= 0) close(s->listen_fd);
    pthread_mutex_destroy(&s->st_lock);
    free(s);
}

int plcrt_slave_start(plcrt_t *rt, const char *host, int port)
{
    if (rt->slave) {
        plcrt_seterr(rt, "the Modbus slave is already running on port %d", rt->slave->port);
        return -1;
    }
    struct plcrt_slave *s = calloc(1, sizeof *s);
    if (!s) { plcrt_seterr(rt, "out of memory"); return -1; }
    pthread_mutex_init(&s->st_lock, NULL);
    s->listen_fd = -1;
    s->idle_ns = PLCRT_SLAVE_IDLE_TIMEOUT_NS;
    s->byte_ns = PLCRT_SLAVE_BYTE_TIMEOUT_NS;
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_port = htons((uint16_t)port);
    if (inet_pton(AF_INET, host, &addr.sin_addr) != 1) {
        plcrt_seterr(rt, "slave: '%s' is not an IPv4 address", host);
        plcrt_slave_free(s);
        return -1;
    }
    s->listen_fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    int one = 1;
    if (s->listen_fd >= 0) setsockopt(s->listen_fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (s->listen_fd < 0 || bind(s->listen_fd, (struct sockaddr *)&addr, sizeof addr) != 0 ||
        listen(s->listen_fd, 64) != 0) {
        plcrt_seterr(rt, "slave: cannot listen on %s:%d: %s", host, port, strerror(errno));
        plcrt_slave_free(s);
        return -1;
    }
    socklen_t len = sizeof addr;
    getsockname(s->listen_fd, (struct sockaddr *)&addr, &len);
    s->port = ntohs(addr.sin_port);
    rt->slave = s;
    plcrt_log(rt, "Modbus slave listening on %s:%d", host, s->port);
    if (rt->mode == PLCRT_REALTIME && rt->started) return plcrt_slave_start_thread(rt);
    return 0;
}

int plcrt_slave_port(const plcrt_t *rt) { return rt->slave ? rt->slave->port : 0; }

int plcrt_slave_set_timeouts(plcrt_t *rt, uint64_t idle_ns, uint64_t byte_ns)
{
    if (!rt->slave || idle_ns == 0 || byte_ns == 0) {
        plcrt_seterr(rt, rt->slave ? "slave: timeouts must be > 0" : "slave: not started");
        return -1;
    }
    rt->slave->idle_ns = idle_ns;
    rt->slave->byte_ns = byte_ns;
    return 0;
}

int plcrt_slave_stats(const plcrt_t *rt, plcrt_slave_stats_t *out)
{
    struct plcrt_slave *s = rt->slave;
    if (!s) return -1;
    pthread_mutex_lock(&s->st_lock);
    *out = s->st;
    pthread_mutex_unlock(&s->st_lock);
    return 0;
}

static void count(struct plcrt_slave *s, uint64_t *field)
{
    pthread_mutex_lock(&s->st_lock);
    (*field)++;
    s->st.clients = (uint64_t)s->n_conns;
    pthread_mutex_unlock(&s->st_lock);
}

/* ------------------------------------------------------------------ requests */

static int get16(const uint8_t *p) { return (p[0] << 8) | p[1]; }
static void put16(uint8_t *p, int v) { p[0] = (uint8_t)(v >> 8); p[1] = (uint8_t)v; }

/* What a request asks for, decoded and checked without touching the image. */
typedef struct decoded {
    int fc, addr, qty;
    int exception;     /* 0, or the Modbus exception code of the reply */
    const uint8_t *data; /* write data in the request */
} decoded_t;

static int register_table_size(int fc) { return fc == 4 ? PLCRT_IMAGE_SIZE : 2 * PLCRT_IMAGE_SIZE; }

static void decode(const uint8_t *pdu, int n, decoded_t *d)
{
    memset(d, 0, sizeof *d);
    d->fc = pdu[0];
    int fc = d->fc;
    if (fc != 1 && fc != 2 && fc != 3 && fc != 4 && fc != 5 && fc != 6 && fc != 15 && fc != 16) {
        d->exception = 1; /* illegal function */
        return;
    }
    /* every function we serve has an address and a quantity or value */
    if (n < 5) { d->exception = 3; return; }
    d->addr = get16(pdu + 1);
    d->qty = get16(pdu + 3);
    int limit, qmax;
    switch (fc) {
    case 1: case 2:
        if (n != 5 || d->qty < 1 || d->qty > 2000) { d->exception = 3; return; }
        limit = NBITS;
        break;
    case 3: case 4:
        if (n != 5 || d->qty < 1 || d->qty > 125) { d->exception = 3; return; }
        limit = register_table_size(fc);
        break;
    case 5:
        if (n != 5 || (d->qty != 0 && d->qty != 0xFF00)) { d->exception = 3; return; }
        d->data = pdu + 3;
        if (d->addr >= NBITS) d->exception = 2;
        d->qty = 1;
        return;
    case 6:
        if (n != 5) { d->exception = 3; return; }
        d->data = pdu + 3;
        if (d->addr >= register_table_size(fc)) d->exception = 2;
        d->qty = 1;
        return;
    case 15: case 16:
        qmax = fc == 15 ? 1968 : 123;
        if (n < 6 || d->qty < 1 || d->qty > qmax) { d->exception = 3; return; }
        {
            int bytes = fc == 15 ? (d->qty + 7) / 8 : 2 * d->qty;
            if (pdu[5] != bytes || n != 6 + bytes) { d->exception = 3; return; }
        }
        d->data = pdu + 6;
        limit = fc == 15 ? NBITS : register_table_size(fc);
        break;
    default:
        d->exception = 1;
        return;
    }
    if (d->addr + d->qty > limit) d->exception = 2;
}

/* Copies the registers of a decoded request in or out under the image lock and builds the
 * reply PDU; returns its length. */
static int execute(plcrt_t *rt, const decoded_t *d, uint8_t *rsp, int lock)
{
    if (d->exception) {
        rsp[0] = (uint8_t)(d->fc | 0x80);
        rsp[1] = (uint8_t)d->exception;
        return 2;
    }
    plcrt_image_t *img = &rt->img;
    const uint8_t *ix = &img->ix[0][0];
    uint8_t *qx = &img->qx[0][0];
    int n = 0;
    rsp[n++] = (uint8_t)d->fc;
    if (lock) pthread_mutex_lock(&rt->image_lock);
    switch (d->fc) {
    case 1: case 2: {
        const uint8_t *bits = d->fc == 1 ? qx : ix;
        int bytes = (d->qty + 7) / 8;
        rsp[n++] = (uint8_t)bytes;
        memset(rsp + n, 0, (size_t)bytes);
        for (int i = 0; i < d->qty; i++)
            if (bits[d->addr + i]) rsp[n + i / 8] |= (uint8_t)(1u << (i % 8));
        n += bytes;
        break;
    }
    case 3: case 4:
        rsp[n++] = (uint8_t)(2 * d->qty);
        for (int i = 0; i < d->qty; i++) {
            int a = d->addr + i;
            uint16_t v = d->fc == 4 ? img->iw[a]
                         : a < PLCRT_IMAGE_SIZE ? img->qw[a] : img->mw[a - PLCRT_IMAGE_SIZE];
            put16(rsp + n, v);
            n += 2;
        }
        break;
    case 5:
        qx[d->addr] = d->data[0] == 0xFF;
        break;
    case 6: case 16:
        for (int i = 0; i < d->qty; i++) {
            int a = d->addr + i;
            uint16_t v = (uint16_t)get16(d->data + 2 * i);
            if (a < PLCRT_IMAGE_SIZE) img->qw[a] = v;
            else img->mw[a - PLCRT_IMAGE_SIZE] = v;
        }
        /* [slave] watch: the program cannot tell a write of the value already there from no
         * write; the count, changed under the same lock as the register, tells it */
        if (rt->slave_watch_count >= 0 && d->addr <= rt->slave_watch &&
            rt->slave_watch < d->addr + d->qty)
            img->iw[rt->slave_watch_count]++;
        break;
    case 15:
        for (int i = 0; i < d->qty; i++) qx[d->addr + i] = (d->data[i / 8] >> (i % 8)) & 1;
        break;
    }
    if (lock) pthread_mutex_unlock(&rt->image_lock);
    if (d->fc == 5 || d->fc == 6) {
        put16(rsp + n, d->addr); n += 2;
        memcpy(rsp + n, d->data, 2); n += 2;
    } else if (d->fc == 15 || d->fc == 16) {
        put16(rsp + n, d->addr); n += 2;
        put16(rsp + n, d->qty); n += 2;
    }
    return n;
}

int plcrt_slave_process_adu(plcrt_t *rt, const uint8_t *adu, size_t len, uint8_t *reply, int lock)
{
    if (len < MBAP + 1 || get16(adu + 2) != 0) return -1;
    int plen = get16(adu + 4); /* unit id + PDU */
    if (plen < 2 || plen > MAX_ADU - 6 || (size_t)(6 + plen) != len) return -1;
    decoded_t d;
    decode(adu + MBAP, plen - 1, &d);
    int n = execute(rt, &d, reply + MBAP, lock);
    memcpy(reply, adu, 2);  /* transaction id */
    put16(reply + 2, 0);
    put16(reply + 4, n + 1);
    reply[6] = adu[6];      /* unit id: answered for every unit, like OpenPLC */
    if (rt->slave) {
        count(rt->slave, &rt->slave->st.requests);
        if (d.exception) count(rt->slave, &rt->slave->st.exceptions);
    }
    return MBAP + n;
}

/* ------------------------------------------------------------------ connections */

static void drop_conn(struct plcrt_slave *s, int i, uint64_t *reason)
{
    close(s->conns[i].fd);
    s->conns[i] = s->conns[--s->n_conns];
    count(s, reason);
}

static void add_conn(struct plcrt_slave *s, int fd, uint64_t now)
{
    if (s->n_conns == PLCRT_SLAVE_MAX_CLIENTS) {
        int oldest = 0;
        for (int i = 1; i < s->n_conns; i++)
            if (s->conns[i].last_ns < s->conns[oldest].last_ns) oldest = i;
        drop_conn(s, oldest, &s->st.evicted);
    }
    conn_t *c = &s->conns[s->n_conns++];
    memset(c, 0, sizeof *c);
    c->fd = fd;
    c->last_ns = now;
    count(s, &s->st.accepted);
}

static void accept_all(struct plcrt_slave *s, uint64_t now)
{
    /* a bounded number per pass: a flood of connections cannot hold up the served clients */
    for (int n = 0; n < 16; n++) {
        int fd = accept4(s->listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) return; /* EAGAIN, or a transient error (EMFILE, ECONNABORTED): next pass */
        add_conn(s, fd, now);
    }
}

/* Sends what is pending; 0 ok (maybe partly), -1 when the connection is gone. */
static int flush_out(conn_t *c, uint64_t now)
{
    while (c->out_off < c->out_len) {
        ssize_t k = send(c->fd, c->out + c->out_off, c->out_len - c->out_off,
                         MSG_DONTWAIT | MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
        if (k <= 0) return -1;
        c->out_off += (size_t)k;
        c->last_ns = now;
    }
    c->out_len = c->out_off = 0;
    return 0;
}

/* Reads at most up to the end of one request; serves it when complete. 1 served, 0 not yet,
 * -1 closed by the peer, -2 framing broken. */
static int read_conn(plcrt_t *rt, conn_t *c, uint64_t now, int lock)
{
    size_t need = c->in_len < MBAP ? MBAP - c->in_len : 0;
    if (c->in_len >= 6) {
        int plen = get16(c->in + 4);
        if (get16(c->in + 2) != 0 || plen < 2 || plen > MAX_ADU - 6) return -2;
        need = (size_t)(6 + plen) - c->in_len;
    }
    if (need) {
        ssize_t k = recv(c->fd, c->in + c->in_len, need, MSG_DONTWAIT);
        if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return 0;
        if (k <= 0) return -1;
        c->in_len += (size_t)k;
        c->last_ns = now;
        if (c->in_len >= 6) {
            int plen = get16(c->in + 4);
            if (get16(c->in + 2) != 0 || plen < 2 || plen > MAX_ADU - 6) return -2;
            if (c->in_len < (size_t)(6 + plen)) return 0;
        } else {
            return 0;
        }
    }
    int n = plcrt_slave_process_adu(rt, c->in, c->in_len, c->out, lock);
    c->in_len = 0;
    if (n < 0) return -2;
    c->out_len = (size_t)n;
    c->out_off = 0;
    return 1;
}

/* One pass: waits up to timeout_ms for activity, then accepts new connections, reads at most
 * one request per ready connection, sends replies and applies the timeouts. */
static int serve_pass(plcrt_t *rt, int timeout_ms, int lock)
{
    struct plcrt_slave *s = rt->slave;
    struct pollfd pfd[PLCRT_SLAVE_MAX_CLIENTS + 1];
    uint64_t now = plcrt_monotonic_ns();
    /* wake up in time for the nearest connection timeout */
    for (int i = 0; i < s->n_conns; i++) {
        conn_t *c = &s->conns[i];
        uint64_t limit = c->last_ns + (c->in_len ? s->byte_ns : s->idle_ns);
        int ms = limit <= now ? 0 : (int)((limit - now) / 1000000ull) + 1;
        if (ms < timeout_ms) timeout_ms = ms;
    }
    pfd[0].fd = s->listen_fd;
    pfd[0].events = POLLIN;
    for (int i = 0; i < s->n_conns; i++) {
        pfd[i + 1].fd = s->conns[i].fd;
        /* while a reply is pending, read nothing more from that client */
        pfd[i + 1].events = s->conns[i].out_len ? POLLOUT : POLLIN;
        pfd[i + 1].revents = 0;
    }
    int n_polled = s->n_conns;
    int ready = poll(pfd, (nfds_t)n_polled + 1, timeout_ms);
    if (ready < 0) return 0;
    now = plcrt_monotonic_ns();
    int served = 0;
    /* connections last to first: drop_conn moves the last one into the freed slot */
    for (int i = n_polled - 1; i >= 0; i--) {
        conn_t *c = &s->conns[i];
        short ev = pfd[i + 1].revents;
        if (ev & (POLLIN | POLLHUP | POLLERR)) {
            if (c->out_len) {
                if (flush_out(c, now) < 0) { drop_conn(s, i, &s->st.closed); continue; }
            } else {
                int rc = read_conn(rt, c, now, lock);
                if (rc == -1) { drop_conn(s, i, &s->st.closed); continue; }
                if (rc == -2) { drop_conn(s, i, &s->st.bad_frames); continue; }
                if (rc == 1) {
                    served++;
                    if (flush_out(c, now) < 0) { drop_conn(s, i, &s->st.closed); continue; }
                }
            }
        } else if (ev & POLLOUT) {
            if (flush_out(c, now) < 0) { drop_conn(s, i, &s->st.closed); continue; }
        }
        if (c->in_len && now - c->last_ns > s->byte_ns) drop_conn(s, i, &s->st.timeouts);
        else if (!c->in_len && now - c->last_ns > s->idle_ns) drop_conn(s, i, &s->st.timeouts);
    }
    if (pfd[0].revents & POLLIN) accept_all(s, now);
    return served;
}

/* Virtual mode: serve what is ready (waiting up to timeout_ms for the first activity), a
 * bounded number of passes so a flood of requests cannot hold the scan. */
int plcrt_slave_poll(plcrt_t *rt, int timeout_ms)
{
    if (!rt->slave) return 0;
    int served = 0;
    for (int pass = 0; pass < 8; pass++) {
        int k = serve_pass(rt, pass ? 0 : timeout_ms, 1);
        served += k;
        if (k == 0 && pass > 0) break;
    }
    return served;
}

int plcrt_slave_add_client(plcrt_t *rt, int fd)
{
    struct plcrt_slave *s = rt->slave;
    if (!s || fd < 0) return -1;
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) return -1;
    add_conn(s, fd, plcrt_monotonic_ns());
    return 0;
}

static void *slave_thread(void *arg)
{
    plcrt_t *rt = arg;
    while (!rt->slave->stop) serve_pass(rt, 100, 1);
    return NULL;
}

int plcrt_slave_start_thread(plcrt_t *rt)
{
    struct plcrt_slave *s = rt->slave;
    if (!s || s->thread_running) return 0;
    s->stop = 0;
    if (pthread_create(&s->thread, NULL, slave_thread, rt) != 0) {
        plcrt_seterr(rt, "cannot start the Modbus slave thread");
        return -1;
    }
    s->thread_running = 1;
    return 0;
}

void plcrt_slave_stop_thread(plcrt_t *rt)
{
    struct plcrt_slave *s = rt->slave;
    if (!s || !s->thread_running) return;
    s->stop = 1;
    pthread_join(s->thread, NULL);
    s->thread_running = 0;
}
