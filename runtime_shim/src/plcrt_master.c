/* Modbus TCP master: one request per range (an MBAP frame with its own transaction id, then the
 * transport seam's after_send hook, then modbus_receive_confirmation), policies cycle /
 * change / trigger, reconnect with backoff. Data meet the image only in the exchange
 * functions, which the scan loop calls between scans. */
#include "plcrt_master.h"

#include <errno.h>
#include <stdarg.h>
#include <poll.h>
#include <sys/socket.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <time.h>
#include <limits.h>

#define STATUS_TRANSPORT(e) (1000 + ((e) > 0 && (e) < 64000 ? (e) : EPROTO))

static uint8_t *ix_bits(plcrt_t *rt) { return &rt->img.ix[0][0]; }
static uint8_t *qx_bits(plcrt_t *rt) { return &rt->img.qx[0][0]; }

/* m->lock guards what the real-time master thread shares with the scan; in virtual mode there
 * is no such thread and no locking (plcrt_lock). */
static void mlock(struct plcrt_master *m) { plcrt_lock(m->rt, &m->lock); }
static void munlock(struct plcrt_master *m) { plcrt_unlock(m->rt, &m->lock); }

void plcrt_master_free(struct plcrt_master *m)
{
    if (!m) return;
    plcrt_master_stop_thread(m);
    for (int i = 0; i < m->n_devices; i++) {
        plcrt_device_t *d = &m->devices[i];
        if (d->ctx && d->rtu && d->bus != i) continue; /* the line's owner frees the context */
        if (d->ctx) {
            if (d->ext_fd >= 0) modbus_set_socket(d->ctx, -1); /* the fd is the caller's */
            else modbus_close(d->ctx);
            modbus_free(d->ctx);
        }
    }
    for (int i = 0; i < m->n_devices; i++) free(m->devices[i].line_req);
    pthread_mutex_destroy(&m->lock);
    pthread_cond_destroy(&m->wake);
    free(m->devices);
    free(m->ranges);
    free(m);
}

int plcrt_master_is_empty(const struct plcrt_master *m) { return !m || m->n_ranges == 0; }

/* ------------------------------------------------------------------ exchange (image side) */

/* The unit id of a request taken now (image_lock held): the device's constant, or the value of
 * its unit_id = %QWn word, which may be outside 0..255 (the request then fails in step). */
static int unit_now(plcrt_t *rt, const plcrt_device_t *d)
{
    return d->unit_word >= 0 ? rt->img.qw[d->unit_word] : d->unit_id;
}

/* the outputs of write range r as they are in the image now (registers, or 0/1 per coil) */
static void take_outputs(plcrt_t *rt, const plcrt_range_t *r, uint16_t *dst)
{
    if (r->table == 'c') {
        const uint8_t *src = qx_bits(rt) + r->image;
        for (int j = 0; j < r->size; j++) dst[j] = src[j];
    } else {
        memcpy(dst, &rt->img.qw[r->image], sizeof dst[0] * (size_t)r->size);
    }
}

int plcrt_master_exchange_out(plcrt_t *rt, struct plcrt_master *m)
{
    int wake = 0, busy = 0; /* busy: a request pending, or a cycle/change range */
    mlock(m);
    for (int i = 0; i < m->n_ranges; i++) {
        plcrt_range_t *r = &m->ranges[i];
        if (r->policy != POLICY_TRIGGER) {
            /* cycle/change: the data of the next poll, as they are now */
            if (r->is_write) {
                take_outputs(rt, r, r->out);
                r->out_len = r->length >= 0 ? rt->img.qw[r->length] : r->size;
            }
            r->out_unit = unit_now(rt, &m->devices[r->dev]);
            busy = 1;
            continue;
        }
        int level = qx_bits(rt)[r->trigger] != 0;
        if (level && !r->trig_level && !r->pending) {
            /* rising edge: the request takes the data, length and unit id as they are now
             * (only here: an idle scan copies nothing) */
            r->pending = 1;
            r->result = RESULT_NONE;
            if (r->is_write) {
                take_outputs(rt, r, r->req);
            }
            r->req_len = r->length >= 0 ? rt->img.qw[r->length] : r->size;
            r->req_addr = r->address >= 0 ? rt->img.qw[r->address] : r->start;
            r->req_unit = unit_now(rt, &m->devices[r->dev]);
            wake = 1;
        }
        r->trig_level = level;
        busy |= r->pending;
    }
    if (wake && plcrt_threaded(rt)) pthread_cond_signal(&m->wake);
    munlock(m);
    return busy;
}

void plcrt_master_exchange_in(plcrt_t *rt, struct plcrt_master *m)
{
    mlock(m);
    for (int i = 0; i < m->n_ranges; i++) {
        plcrt_range_t *r = &m->ranges[i];
        int bits = r->table == 'c' || r->table == 'd';
        if (r->policy == POLICY_TRIGGER) {
            if (!r->trig_level) {
                /* the program dropped the trigger: handshake over */
                ix_bits(rt)[r->done] = 0;
                ix_bits(rt)[r->error] = 0;
                r->done_shown = r->error_shown = 0;
                if (!r->pending) r->result = RESULT_NONE;
                continue;
            }
            if (r->result == RESULT_NONE) continue;
            if (r->result == RESULT_OK && !r->is_write) {
                /* (a length word: the registers read; the rest of the image stays) */
                int n = r->req_len >= 1 && r->req_len <= r->size ? r->req_len : r->size;
                for (int j = 0; j < n; j++) {
                    if (bits) ix_bits(rt)[r->image + j] = (uint8_t)(r->in[j] != 0);
                    else rt->img.iw[r->image + j] = r->in[j];
                }
            }
            ix_bits(rt)[r->done] = r->result == RESULT_OK;
            ix_bits(rt)[r->error] = r->result == RESULT_ERROR;
            if (r->status >= 0) rt->img.iw[r->status] = (uint16_t)r->status_value;
            r->result = RESULT_NONE;
            continue;
        }
        /* cycle / change: the last request's result, held until the next one ends */
        if (r->error >= 0) ix_bits(rt)[r->error] = r->status_value != 0;
        if (r->status >= 0) rt->img.iw[r->status] = (uint16_t)r->status_value;
        if (!r->is_write && r->fresh) {
            for (int j = 0; j < r->size; j++) {
                if (bits) ix_bits(rt)[r->image + j] = (uint8_t)(r->in[j] != 0);
                else rt->img.iw[r->image + j] = r->in[j];
            }
            r->fresh = 0;
        }
    }
    for (int i = 0; i < m->n_devices; i++) {
        plcrt_device_t *d = &m->devices[i];
        if (d->errors_word >= 0) rt->img.iw[d->errors_word] = (uint16_t)d->n_errors;
        if (d->online_bit >= 0) ix_bits(rt)[d->online_bit] = (uint8_t)d->connected;
    }
    munlock(m);
}

/* ------------------------------------------------------------------ rate-limited log */

enum { LOG_CONNECTED, LOG_FAILING, LOG_RECOVERED, LOG_LENGTH, LOG_UNIT };

/* Logs a device's transition line unless one of the same kind was logged less than
 * PLCRT_LOG_INTERVAL_NS ago (time now: virtual or monotonic); suppressed lines are counted
 * and the count is appended to the next line of that kind. */
static void log_limited(plcrt_t *rt, plcrt_device_t *d, int kind, uint64_t now, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static void log_limited(plcrt_t *rt, plcrt_device_t *d, int kind, uint64_t now, const char *fmt, ...)
{
    if (d->log_seen[kind] && now - d->log_last_ns[kind] < PLCRT_LOG_INTERVAL_NS) {
        d->log_suppressed[kind]++;
        return;
    }
    char line[520];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (d->log_suppressed[kind])
        plcrt_log(rt, "%s (and %llu such lines not logged in the last %llu s)", line,
                  (unsigned long long)d->log_suppressed[kind],
                  (unsigned long long)(PLCRT_LOG_INTERVAL_NS / 1000000000ull));
    else
        plcrt_log(rt, "%s", line);
    d->log_seen[kind] = 1;
    d->log_last_ns[kind] = now;
    d->log_suppressed[kind] = 0;
}

/* ------------------------------------------------------------------ transport */

static void device_close(plcrt_device_t *d)
{
    if (d->ctx && d->ext_fd < 0) modbus_close(d->ctx);
    d->connected = d->ext_fd >= 0;
}

static int device_ensure_ctx(plcrt_t *rt, plcrt_device_t *d)
{
    if (d->ctx) return 0;
    if (d->rtu)
        d->ctx = modbus_new_rtu(d->host, d->baud, d->line_parity ? d->line_parity : d->parity,
                                d->data_bits, d->stop_bits);
    else
        d->ctx = modbus_new_tcp(d->host[0] ? d->host : "127.0.0.1", d->port);
    if (!d->ctx) {
        plcrt_log(rt, "device %s: cannot create a Modbus context: %s", d->name, modbus_strerror(errno));
        return -1;
    }
    /* (libmodbus's slave id is not used: send_adu frames unit id and PDU itself, with the
     * request's unit id, and modbus_receive_confirmation does not check the unit id over TCP;
     * do_request compares it with the request's) */
    modbus_set_slave(d->ctx, d->unit_id);
    modbus_set_error_recovery(d->ctx, MODBUS_ERROR_RECOVERY_NONE);
    modbus_set_response_timeout(d->ctx, (uint32_t)(d->timeout_ns / 1000000000ull),
                                (uint32_t)((d->timeout_ns % 1000000000ull) / 1000));
    if (d->ext_fd >= 0) {
        modbus_set_socket(d->ctx, d->ext_fd);
        d->connected = 1;
    }
    return 0;
}

/* Linux: is path (after symlinks) the slave side of a Unix98 pseudo-terminal (/dev/pts/N, majors
 * 136..143, Documentation/admin-guide/devices.txt)? Its path into real. A pty keeps no parity:
 * the kernel's pty driver clears PARENB (and sets CS8) on every tcsetattr. */
static int is_pty(const char *path, char *real, size_t n)
{
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISCHR(st.st_mode)) return 0;
    if (major(st.st_rdev) < 136 || major(st.st_rdev) > 143) return 0;
    char buf[PATH_MAX];
    snprintf(real, n, "%s", realpath(path, buf) ? buf : path);
    return 1;
}

static const char *parity_name(char p) { return p == 'E' ? "even" : p == 'O' ? "odd" : "none"; }

/* Serial line owner d with parity: is its line a pty? Then it is opened without parity, and that
 * is said once (at start, or at the first open when the line was not there at start): asking a
 * pty for parity again, with nothing else to change, makes tcsetattr fail with EINVAL (Linux),
 * which is how a plcrt started after a killed one never talked again. The configured parity
 * still counts in the line's timing (virtual time). */
static int rtu_pty_without_parity(plcrt_t *rt, plcrt_device_t *d)
{
    char real[PATH_MAX];
    if (d->parity == 'N' || d->line_no_parity || !is_pty(d->host, real, sizeof real)) return 0;
    if (!d->line_noted)
        plcrt_log(rt, "device %s: %s%s%s is a pseudo-terminal, which carries no parity: opened "
                  "without parity (parity %s is the line's setting for its timing only)", d->name,
                  d->host, strcmp(real, d->host) ? " -> " : "", strcmp(real, d->host) ? real : "",
                  parity_name(d->parity));
    d->line_noted = 1;
    return 1;
}

void plcrt_master_note_lines(plcrt_t *rt, struct plcrt_master *m)
{
    for (int i = 0; m && i < m->n_devices; i++) {
        plcrt_device_t *d = &m->devices[i];
        if (d->rtu && d->bus == i && d->ext_fd < 0 && !d->transact) rtu_pty_without_parity(rt, d);
    }
}

/* Serial line owner d, before it is opened: the parity to open it with, none on a line that
 * carries none (a pty; a tty that dropped PARENB or refused it before); the context is made anew
 * when that changes. */
static int rtu_line_setup(plcrt_t *rt, plcrt_device_t *d)
{
    char want = d->parity;
    if (d->line_no_parity || rtu_pty_without_parity(rt, d)) want = 'N';
    if (d->ctx && want == d->line_parity) return 0;
    if (d->ctx) {
        modbus_free(d->ctx); /* closed: only called while not connected */
        d->ctx = NULL;
    }
    d->line_parity = want;
    return device_ensure_ctx(rt, d);
}

/* Serial line owner d, just opened with parity: did the tty keep it? (Some drivers clear PARENB
 * instead of failing.) If not, the line carries none: said once, and opened without from now on. */
static void rtu_line_check(plcrt_t *rt, plcrt_device_t *d)
{
    struct termios t;
    if (d->line_parity == 'N' || tcgetattr(modbus_get_socket(d->ctx), &t) != 0 || (t.c_cflag & PARENB))
        return;
    d->line_no_parity = 1;
    if (!d->line_noted)
        plcrt_log(rt, "device %s: %s did not keep parity %s (the tty cleared it): the line carries no "
                  "parity", d->name, d->host, parity_name(d->parity));
    d->line_noted = 1;
}

/* 0 when connected; -1 with the errno to report; -2 while waiting for the reconnect backoff
 * (*err: the error of the last attempt, or ENOTCONN after a failed request closed it) */
static int device_connect(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *d, uint64_t now,
                          int *err)
{
    if (d->transact) return 0; /* in process: always there */
    if (d->rtu && d->bus != (int)(d - m->devices)) {
        /* a further device on a serial line: the line is the first device's */
        plcrt_device_t *o = &m->devices[d->bus];
        int rc = device_connect(rt, m, o, now, err);
        if (rc != 0) return rc;
        d->ctx = o->ctx;
        d->connected = 1;
        return 0;
    }
    if (d->connected && d->ctx) return 0;
    if (now < d->next_connect_ns) {
        *err = d->connect_err ? d->connect_err : ENOTCONN;
        return -2;
    }
    if ((d->rtu && d->ext_fd < 0 ? rtu_line_setup(rt, d) : device_ensure_ctx(rt, d)) != 0) {
        *err = ENOMEM;
        return -1;
    }
    if (d->connected) return 0;
    int rc = modbus_connect(d->ctx);
    if (rc != 0 && errno == EINVAL && d->rtu && d->line_parity != 'N') {
        /* a tty that refuses the parity (a pty left as a killed client set it, with nothing else
         * to change): open it without, and say so once */
        d->line_no_parity = 1;
        if (rtu_line_setup(rt, d) == 0 && (rc = modbus_connect(d->ctx)) == 0) {
            if (!d->line_noted)
                plcrt_log(rt, "device %s: %s refuses parity %s (Invalid argument): opened without parity",
                          d->name, d->host, parity_name(d->parity));
            d->line_noted = 1;
        } else {
            d->line_no_parity = 0;
            errno = EINVAL;
        }
    }
    if (rc == 0) {
        mlock(m);
        d->connected = 1;
        d->n_connects++;
        munlock(m);
        d->backoff_ns = 0;
        d->connect_err = 0;
        if (d->rtu) rtu_line_check(rt, d);
        if (d->rtu && d->reopen_why[0])
            log_limited(rt, d, LOG_CONNECTED, now, "device %s: reopened %s (closed after: %s)", d->name,
                        d->host, d->reopen_why);
        else if (d->n_connects > 1 || d->failing) {
            if (d->rtu)
                log_limited(rt, d, LOG_CONNECTED, now, "device %s: opened %s", d->name, d->host);
            else
                log_limited(rt, d, LOG_CONNECTED, now, "device %s: connected to %s:%d", d->name, d->host, d->port);
        }
        d->reopen_why[0] = 0;
        return 0;
    }
    *err = errno;
    d->connect_err = errno;
    d->backoff_ns = d->backoff_ns ? d->backoff_ns * 2 : m->reconnect_min_ns;
    if (d->backoff_ns > m->reconnect_max_ns) d->backoff_ns = m->reconnect_max_ns;
    d->next_connect_ns = now + d->backoff_ns;
    return -1;
}

static void put16(uint8_t *p, int v) { p[0] = (uint8_t)(v >> 8); p[1] = (uint8_t)v; }
static int get16(const uint8_t *p) { return (p[0] << 8) | p[1]; }

/* Frames unit id + PDU (n bytes) as a Modbus TCP ADU with the device's next transaction id
 * (never 0 after wrapping); returns the ADU length. One framing for TCP and in process. */
static int frame_adu(plcrt_device_t *d, const uint8_t *req, int n, uint8_t *adu)
{
    d->tid = (uint16_t)(d->tid + 1) ? (uint16_t)(d->tid + 1) : 1;
    put16(adu, d->tid);
    put16(adu + 2, 0);
    put16(adu + 4, n);
    memcpy(adu + 6, req, (size_t)n);
    return n + 6;
}

/* Sends unit id + PDU with an MBAP header of our own: libmodbus's modbus_send_raw_request
 * always sends transaction id 0, so a stale reply could not be told from the right one. */
static int send_adu(plcrt_device_t *d, const uint8_t *req, int n, uint16_t *tid)
{
    uint8_t adu[MODBUS_TCP_MAX_ADU_LENGTH];
    frame_adu(d, req, n, adu);
    *tid = d->tid;
    int fd = modbus_get_socket(d->ctx);
    for (int off = 0; off < n + 6;) {
        ssize_t k = send(fd, adu + off, (size_t)(n + 6 - off), MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            struct pollfd p = {fd, POLLOUT, 0};
            if (poll(&p, 1, (int)(d->timeout_ns / 1000000ull) + 1) == 1) continue;
            errno = ETIMEDOUT;
            return -1;
        }
        if (k <= 0) return -1;
        off += (int)k;
    }
    return 0;
}

/* Receives the reply with transaction id tid within the device's timeout; replies with
 * another id (late or duplicated answers to earlier requests) are dropped and counted. */
static int receive_reply(struct plcrt_master *m, plcrt_device_t *d, uint16_t tid, uint8_t *rsp)
{
    uint64_t deadline = plcrt_monotonic_ns() + d->timeout_ns;
    int len;
    for (;;) {
        len = modbus_receive_confirmation(d->ctx, rsp);
        if (len < 2 || get16(rsp) == tid) break;
        mlock(m);
        uint64_t n = ++d->n_stale;
        munlock(m);
        if (n == 1 || n % 100 == 0)
            plcrt_log(m->rt, "device %s: dropped a reply with transaction id %d, expected %d "
                      "(%llu dropped so far)", d->name, get16(rsp), tid, (unsigned long long)n);
        uint64_t now = plcrt_monotonic_ns();
        if (now >= deadline) {
            errno = ETIMEDOUT;
            len = -1;
            break;
        }
        uint64_t left = deadline - now; /* the drops do not extend the timeout */
        modbus_set_response_timeout(d->ctx, (uint32_t)(left / 1000000000ull),
                                    (uint32_t)((left % 1000000000ull) / 1000));
    }
    modbus_set_response_timeout(d->ctx, (uint32_t)(d->timeout_ns / 1000000000ull),
                                (uint32_t)((d->timeout_ns % 1000000000ull) / 1000));
    return len;
}

/* One request over the device's transport. Returns 0, or the status for the program:
 * a Modbus exception code 1..255, or 1000+errno for transport errors (then *transport = 1). */
static int do_request(struct plcrt_master *m, plcrt_device_t *d, request_t *q, int *transport)
{
    uint8_t req[MODBUS_TCP_MAX_ADU_LENGTH];
    uint8_t rsp[MODBUS_TCP_MAX_ADU_LENGTH + 64]; /* + room for an in-process handler's cap */
    int n = 0;
    *transport = 0;
    req[n++] = (uint8_t)q->unit; /* the request's own: unit_id = %QWn may change per request */
    req[n++] = (uint8_t)q->fc;
    put16(req + n, q->addr); n += 2;
    put16(req + n, q->count); n += 2;
    if (q->fc == 16) {
        req[n++] = (uint8_t)(q->count * 2);
        for (int i = 0; i < q->count; i++) { put16(req + n, q->data[i]); n += 2; }
    } else if (q->fc == 23) {
        /* read address and quantity above, then the write part (written first by the slave) */
        put16(req + n, q->waddr); n += 2;
        put16(req + n, q->wcount); n += 2;
        req[n++] = (uint8_t)(q->wcount * 2);
        for (int i = 0; i < q->wcount; i++) { put16(req + n, q->wdata[i]); n += 2; }
    } else if (q->fc == 15) {
        int bytes = (q->count + 7) / 8;
        req[n++] = (uint8_t)bytes;
        memset(req + n, 0, (size_t)bytes);
        for (int i = 0; i < q->count; i++)
            if (q->data[i]) req[n + i / 8] |= (uint8_t)(1u << (i % 8));
        n += bytes;
    }
    int len, h;
    if (d->transact) {
        /* in-process transport: the request ADU exactly as send_adu frames it for TCP (MBAP
         * with a new transaction id, protocol 0, length) to the handler; the reply ADU is
         * checked like a TCP reply (same transaction id), then parsed by the code below */
        uint8_t adu[MODBUS_TCP_MAX_ADU_LENGTH];
        long r = d->transact(d->transact_user, adu, (size_t)frame_adu(d, req, n, adu), rsp, sizeof rsp);
        if (r < 0) {
            *transport = 1;
            return STATUS_TRANSPORT(ETIMEDOUT);
        }
        len = (int)r;
        h = 7;
        if (len < h + 1 || len > MODBUS_TCP_MAX_ADU_LENGTH || get16(rsp) != d->tid || get16(rsp + 2) != 0 ||
            get16(rsp + 4) != len - 6)
            goto bad;
    } else if (d->rtu) {
        /* Modbus RTU: unit id + PDU + CRC on the line (libmodbus frames it); the line is shared
         * by the devices on it, one exchange at a time (this thread does them in turn) */
        plcrt_device_t *o = &m->devices[d->bus];
        if (o->pause_ns || d->pause_ns) {
            uint64_t pause = d->pause_ns > o->pause_ns ? d->pause_ns : o->pause_ns;
            uint64_t t = plcrt_monotonic_ns();
            if (o->bus_free_ns && t < o->bus_free_ns + pause) {
                uint64_t w = o->bus_free_ns + pause - t;
                struct timespec ts = {(time_t)(w / 1000000000ull), (long)(w % 1000000000ull)};
                nanosleep(&ts, NULL);
            }
        }
        modbus_flush(d->ctx); /* what a late answer to an earlier request left on the line */
        modbus_set_slave(d->ctx, q->unit);
        modbus_set_response_timeout(d->ctx, (uint32_t)(d->timeout_ns / 1000000000ull),
                                    (uint32_t)((d->timeout_ns % 1000000000ull) / 1000));
        if (modbus_send_raw_request(d->ctx, req, n) < 0) {
            o->bus_free_ns = plcrt_monotonic_ns();
            *transport = 1;
            return STATUS_TRANSPORT(errno);
        }
        if (d->after_send) d->after_send(d->after_send_user);
        if (q->unit == 0) {
            /* broadcast: every slave takes it, none answers */
            o->bus_free_ns = plcrt_monotonic_ns();
            return 0;
        }
        len = modbus_receive_confirmation(d->ctx, rsp);
        o->bus_free_ns = plcrt_monotonic_ns();
        if (len < 0) {
            *transport = 1;
            /* libmodbus's own codes (bad CRC, ...) are no errno: report them as a bad reply */
            return STATUS_TRANSPORT(errno >= MODBUS_ENOBASE ? EPROTO : errno);
        }
        h = 1;
    } else {
        uint16_t tid = 0;
        if (send_adu(d, req, n, &tid) < 0) {
            *transport = 1;
            return STATUS_TRANSPORT(errno);
        }
        if (d->after_send) d->after_send(d->after_send_user);
        len = receive_reply(m, d, tid, rsp);
        if (len < 0) {
            *transport = 1;
            return STATUS_TRANSPORT(errno);
        }
        h = modbus_get_header_length(d->ctx); /* MBAP incl. unit id: the function code follows */
    }
    if (len < h + 2 || rsp[h - 1] != (uint8_t)q->unit) goto bad;
    if (rsp[h] == (uint8_t)(q->fc | 0x80)) return rsp[h + 1] ? rsp[h + 1] : EPROTO + 1000;
    if (rsp[h] != q->fc) goto bad;
    if (q->fc == 3 || q->fc == 4 || q->fc == 23) {
        if (rsp[h + 1] != q->count * 2 || len < h + 2 + q->count * 2) goto bad;
        for (int i = 0; i < q->count; i++) q->data[i] = (uint16_t)get16(rsp + h + 2 + 2 * i);
    } else if (q->fc == 1 || q->fc == 2) {
        int bytes = (q->count + 7) / 8;
        if (rsp[h + 1] != bytes || len < h + 2 + bytes) goto bad;
        for (int i = 0; i < q->count; i++) q->data[i] = (rsp[h + 2 + i / 8] >> (i % 8)) & 1;
    } else {
        if (len < h + 5 || get16(rsp + h + 1) != q->addr || get16(rsp + h + 3) != q->count) goto bad;
    }
    return 0;
bad:
    /* a reply that does not fit the request: treat the stream as out of step */
    *transport = 1;
    return STATUS_TRANSPORT(EPROTO);
}

/* A read of a MIP read area (status word, count word, data) with status_first: the first read
 * takes q->status_first registers from the status word on (2: status and count alone; more: the
 * first data registers too). Only when bit 0 (new read data) is set and the block is longer than
 * what the first read took: a second read from the status word on, of the count's registers
 * (2 + count, at most the range); when that read's count is larger than the one before (a newer,
 * longer block arrived between them), a third read of the whole range. A read that touches the
 * data clears bit 0 in the modem, so a later read of the same block shows it clear: the bit 0 the
 * first read saw is kept in the status word given to the program (the block it announced is the
 * one the later read returns, or a newer one, which sets the bit again). Registers not read keep
 * what the last read brought.
 * The program must never see the first registers of one block with the data of another: the
 * blocks take a new number without bit 0 as a new record (MIP_ReadDecoder). Bit 0 alone cannot
 * promise that: a read whose answer never arrived (a PLC killed while it was on the line, a CRC
 * error) has cleared it in the modem. So the further reads are made also when the image holds no
 * read of this run yet (a restarted PLC) or when the registers the first read took (count, first
 * data) differ from the image's; the image is then always one block, the latest or an older
 * one (issue 38). The characters of the further exchanges are kept for the line's time in
 * virtual time. */
static int status_first_request(struct plcrt_master *m, plcrt_device_t *d, const plcrt_range_t *r,
                                request_t *q, int *transport)
{
    int size = q->count;
    q->extra_req = q->extra_rsp = 0;
    memcpy(q->data, r->in, sizeof q->data[0] * (size_t)size); /* what is not read stays */
    q->count = q->status_first < size ? q->status_first : size;
    int status = do_request(m, d, q, transport);
    int known = r->have_in &&
                !memcmp(q->data + 1, r->in + 1, sizeof q->data[0] * (size_t)(q->count - 1));
    if (status != 0 || (!(q->data[0] & 1) && known) || 2 + q->data[1] <= q->count) {
        q->count = size;
        return status;
    }
    uint16_t seen = q->data[0] & 1;
    for (int pass = 0; pass < 2; pass++) {
        int want = pass ? size : 2 + q->data[1];
        if (want > size) want = size;
        q->count = want;
        q->fc = 3; /* after an FC23 the write is done: plain reads */
        q->extra_req += 8;
        q->extra_rsp += 5 + 2 * want;
        status = do_request(m, d, q, transport);
        if (status != 0) break;
        q->data[0] |= seen;
        if (want == size || 2 + q->data[1] <= want) break;
    }
    q->count = size;
    return status;
}

static const char *status_text(int status, char *buf, size_t n)
{
    if (status >= 1000) snprintf(buf, n, "%s", modbus_strerror(status - 1000));
    else snprintf(buf, n, "Modbus exception %d (%s)", status, modbus_strerror(MODBUS_ENOBASE + status));
    return buf;
}

/* Performs one request of range r at time now; returns the status (0 = ok). */
static int range_request(plcrt_t *rt, struct plcrt_master *m, plcrt_range_t *r, request_t *q,
                         uint64_t now)
{
    plcrt_device_t *d = &m->devices[r->dev];
    int status, transport = 0, err;
    int exchanged = 0, rc = device_connect(rt, m, d, now, &err);
    if (rc != 0) {
        if (rc == -2 && r->policy != POLICY_TRIGGER)
            return -1; /* waiting for the reconnect backoff: no request, no error */
        status = STATUS_TRANSPORT(err);
        transport = 1;
    } else if (q->status_first) {
        status = status_first_request(m, d, r, q, &transport);
    } else {
        status = do_request(m, d, q, &transport);
    }
    exchanged = rc == 0;
    mlock(m); /* counters and state are read by the exchange */
    d->n_requests++;
    if (status != 0) d->n_errors++;
    munlock(m);
    if (status == 0) {
        if (d->rtu) m->devices[d->bus].line_fail_run = 0;
        if (d->failing)
            log_limited(rt, d, LOG_RECOVERED, now, "device %s: requests succeed again (%llu errors so far)",
                        d->name, (unsigned long long)d->n_errors);
        d->failing = 0;
        return 0;
    }
    char why[160];
    status_text(status, why, sizeof why);
    /* log transitions (and every 100th error), not every failed poll of a dead device */
    if (d->n_errors % 100 == 0)
        plcrt_log(rt, "device %s: %s %s %d+%d (range %s) failed: %s; %llu errors", d->name,
                  r->is_write ? "write" : "read",
                  r->table == 'h' ? "holding" : r->table == 'i' ? "input" : r->table == 'c' ? "coils" : "discrete",
                  q->addr, q->count, r->name, why, (unsigned long long)d->n_errors);
    else if (!d->failing)
        log_limited(rt, d, LOG_FAILING, now, "device %s: %s %s %d+%d (range %s) failed: %s; %llu errors", d->name,
                  r->is_write ? "write" : "read",
                  r->table == 'h' ? "holding" : r->table == 'i' ? "input" : r->table == 'c' ? "coils" : "discrete",
                  q->addr, q->count, r->name, why, (unsigned long long)d->n_errors);
    snprintf(d->last_error, sizeof d->last_error, "%s", why);
    d->failing = 1;
    if (d->transact) {
        /* in process nothing can be left in a stream */
    } else if (d->rtu && d->ext_fd < 0) {
        /* a serial line stays open (the next request flushes what is left on it), unless the
         * system failed on it (EIO: the tty went away, a pty whose other side closed) or its
         * exchanges keep failing: then it is closed, and opened and configured again by the
         * next request */
        plcrt_device_t *o = &m->devices[d->bus];
        int e = status - 1000;
        if (!transport) {
            o->line_fail_run = 0; /* an exception answer: the line works */
        } else if (exchanged && o->connected &&
                   ((e != ETIMEDOUT && e != EPROTO) || ++o->line_fail_run >= PLCRT_SERIAL_REOPEN_AFTER)) {
            snprintf(o->reopen_why, sizeof o->reopen_why, "%s", why);
            mlock(m);
            device_close(o);
            munlock(m);
            o->line_fail_run = 0;
            o->backoff_ns = 0;
            o->next_connect_ns = now; /* at once: the next request opens it */
        }
    } else if (transport && d->connected && d->ext_fd < 0) {
        /* the TCP stream may hold a late answer: start over on a new connection */
        mlock(m);
        device_close(d);
        munlock(m);
        d->backoff_ns = m->reconnect_min_ns;
        d->next_connect_ns = now + d->backoff_ns;
    } else if (transport && d->ext_fd >= 0) {
        modbus_flush(d->ctx);
    }
    return status;
}

static int function_code(const plcrt_range_t *r)
{
    if (r->is_write) return r->table == 'c' ? 15 : 16;
    switch (r->table) {
    case 'i': return 4;
    case 'c': return 1;
    case 'd': return 2;
    default: return 3;
    }
}

/* the result of range r's request q: into the range, for the next exchange */
static void publish(struct plcrt_master *m, plcrt_range_t *r, const request_t *q, int status)
{
    mlock(m);
    if (r->policy == POLICY_TRIGGER) {
        r->pending = 0;
        r->status_value = status;
        r->result = status == 0 ? RESULT_OK : RESULT_ERROR;
        if (status == 0 && !r->is_write) {
            memcpy(r->in, q->data, sizeof q->data[0] * (size_t)r->size);
            r->have_in = 1;
        }
    } else if ((r->status_value = status) == 0) {
        if (r->is_write) {
            memcpy(r->last, q->data, sizeof q->data[0] * (size_t)r->size);
            r->have_last = 1;
        } else {
            memcpy(r->in, q->data, sizeof q->data[0] * (size_t)r->size);
            r->fresh = 1;
            r->have_in = 1;
        }
    }
    munlock(m);
}

/* ---- serial line in virtual time
 * In virtual mode an RTU device's exchange takes the time it takes on the wire: the request is
 * taken at t, reaches the slave (the transport, the emulator core) when its last character has
 * crossed the line, t + (request characters) x (character time); the answer follows one
 * 3.5-character gap later and is shown when its last character has arrived; the next request on
 * the line waits one more gap (and the device's pause). The devices on one line take it in turn.
 * A character is 1 start + data + parity + stop bits; the gap is 1.75 ms above 19200 baud. In
 * real time the line itself takes that time. */

static uint64_t char_ns(const plcrt_device_t *o)
{
    int bits = 1 + o->data_bits + (o->parity != 'N') + o->stop_bits;
    return (uint64_t)bits * 1000000000ull / (uint64_t)(o->baud > 0 ? o->baud : 19200);
}

static uint64_t gap_ns(const plcrt_device_t *o)
{
    return o->baud > 19200 ? 1750000ull : char_ns(o) * 7 / 2;
}

/* RTU frame lengths (unit id + PDU + CRC) of a request and of its answer */
static int rtu_req_chars(const request_t *q)
{
    if (q->fc == 16) return 9 + 2 * q->count;
    if (q->fc == 15) return 9 + (q->count + 7) / 8;
    if (q->fc == 23) return 13 + 2 * q->wcount;
    return 8;
}

static int rtu_rsp_chars(const request_t *q, int status)
{
    if (status > 0 && status < 1000) return 5; /* exception */
    if (q->status_first) return 5 + 2 * (q->status_first < q->count ? q->status_first : q->count); /* the first exchange */
    if (q->fc == 3 || q->fc == 4 || q->fc == 23) return 5 + 2 * q->count;
    if (q->fc == 1 || q->fc == 2) return 5 + (q->count + 7) / 8;
    return 8;
}

static int line_modelled(plcrt_t *rt, const plcrt_device_t *d) { return d->rtu && !plcrt_threaded(rt); }

/* moves the exchange on the line of owner o on to now; returns 1 while the line is busy */
static int line_advance(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *o, uint64_t now)
{
    if (o->line_range < 0) return now < o->line_free_ns;
    plcrt_range_t *r = &m->ranges[o->line_range];
    plcrt_device_t *d = &m->devices[r->dev];
    request_t *q = o->line_req;
    if (o->line_phase == 1) {
        if (now < o->line_send_ns) return 1;
        /* the request is complete at the slave: the transport answers now */
        request_t *w = &m->q;
        memcpy(w, q, sizeof *w);
        int status = range_request(rt, m, r, w, o->line_send_ns);
        if (status < 0) status = STATUS_TRANSPORT(ENOTCONN);
        memcpy(q, w, sizeof *q);
        o->line_status = status;
        o->line_phase = 2;
        if (q->unit == 0)
            o->line_done_ns = o->line_send_ns; /* broadcast: no answer */
        else if (status >= 1000)
            o->line_done_ns = o->line_send_ns + d->timeout_ns; /* silence: the master waits its timeout */
        else
            o->line_done_ns = o->line_send_ns + gap_ns(o) + (uint64_t)rtu_rsp_chars(q, status) * char_ns(o);
        if (q->extra_req) /* status_first's further exchanges, one after the other */
            o->line_done_ns += (uint64_t)(q->extra_req + q->extra_rsp) * char_ns(o) +
                               (uint64_t)(q->extra_req / 8) * 2 * gap_ns(o);
    }
    if (now < o->line_done_ns) return 1;
    publish(m, r, q, o->line_status);
    if (o->line_range2 >= 0) publish(m, &m->ranges[o->line_range2], q, o->line_status);
    o->line_range2 = -1;
    o->line_busy_ns += o->line_done_ns - (o->line_send_ns - (uint64_t)rtu_req_chars(q) * char_ns(o));
    o->line_free_ns = o->line_done_ns + gap_ns(o) + (d->pause_ns > o->pause_ns ? d->pause_ns : o->pause_ns);
    o->line_range = -1;
    return now < o->line_free_ns;
}

/* puts request q of range r on the idle line of owner o. A trigger request starts where the
 * real-time master would start it: when the scan that raised the trigger ended (one tick before
 * this I/O phase; scans take no virtual time), or when the line became free after that; a
 * poll of a cycle / change range starts now. An exchange shorter than the rest of the tick then
 * shows in this scan, as over TCP, and as in real time when it fits into the idle time. */
static int line_start(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *o, plcrt_range_t *r,
                      const request_t *q, uint64_t now, int pair)
{
    uint64_t start = now;
    if (r->policy == POLICY_TRIGGER) {
        start = now >= rt->tick_ns ? now - rt->tick_ns : 0;
        if (start < o->line_free_ns) start = o->line_free_ns;
    }
    o->line_range2 = pair;
    if (!o->line_req && !(o->line_req = malloc(sizeof *o->line_req))) return -1;
    memcpy(o->line_req, q, sizeof *q);
    o->line_range = (int)(r - m->ranges);
    o->line_phase = 1;
    o->line_send_ns = start + (uint64_t)rtu_req_chars(q) * char_ns(o);
    return 0;
}

static void step(plcrt_t *rt, struct plcrt_master *m, uint64_t now, int writes_only)
{
    request_t *q = &m->q; /* large: not on the stack */
    /* virtual time: exchanges on serial lines move on first (they may finish now) */
    for (int i = 0; i < m->n_devices; i++) {
        plcrt_device_t *o = &m->devices[i];
        if (line_modelled(rt, o) && o->bus == i) line_advance(rt, m, o, now);
    }
    /* config order; with serial lines in virtual time the round starts after the range that
     * last took a line, so that the ranges on a line take it in turn (in real time each pass
     * does every due range, one after the other) */
    int first = m->line_rr < m->n_ranges ? m->line_rr : 0;
    for (int k = 0; k < m->n_ranges; k++) {
        int i = (first + k) % m->n_ranges;
        plcrt_range_t *r = &m->ranges[i];
        if (writes_only && (!r->is_write || r->policy == POLICY_TRIGGER)) continue;
        plcrt_device_t *d = &m->devices[r->dev];
        plcrt_device_t *line = line_modelled(rt, d) ? &m->devices[d->bus] : NULL;
        if (line && (line->line_range >= 0 || now < line->line_free_ns)) continue; /* the line is taken */
        mlock(m);
        int go = 0;
        if (r->policy == POLICY_TRIGGER) {
            if (r->pending) {
                go = 1;
                q->count = r->req_len; /* the range's size for reads */
                q->unit = r->req_unit;
                if (r->is_write) memcpy(q->data, r->req, sizeof q->data[0] * (size_t)r->size);
            }
        } else if (r->out_unit >= 0 && now >= r->next_due) {
            /* (out_unit < 0: unit_id = %QWn and no exchange yet, the real-time master thread's
             * first pass before the first scan ended: nothing to take the unit id from) */
            r->next_due = r->next_due + d->poll_ns > now ? r->next_due + d->poll_ns : now + d->poll_ns;
            if (r->next_due == 0) r->next_due = now + d->poll_ns;
            go = 1;
            q->count = r->size;
            q->unit = r->out_unit;
            if (r->is_write) {
                memcpy(q->data, r->out, sizeof q->data[0] * (size_t)r->size);
                q->count = r->out_len;
                if (r->policy == POLICY_CHANGE && r->have_last &&
                    !memcmp(r->last, q->data, sizeof q->data[0] * (size_t)r->size))
                    go = 0;
            }
        }
        if (go && d->fc23 && r->policy == POLICY_TRIGGER && r->is_write && r->table == 'h' &&
            r->req_len <= 121) {
            /* fc23: a write waits for the pending read of its device it goes with (in this pass) */
            int waits = 0;
            for (int j = 0; j < m->n_ranges && !waits; j++) {
                plcrt_range_t *o = &m->ranges[j];
                waits = o->dev == r->dev && !o->is_write && o->table == 'h' &&
                        o->policy == POLICY_TRIGGER && o->pending && o->req_unit == r->req_unit &&
                        (!line || line->line_range != j);
            }
            if (waits && k + 1 < m->n_ranges) {
                munlock(m);
                continue;
            }
        }
        /* fc23: a pending trigger read goes with a pending trigger write of the device as one
         * request (the write first, as the standard has it); writes over 121 registers go alone */
        int pair = -1;
        if (go && d->fc23 && r->policy == POLICY_TRIGGER && !r->is_write && r->table == 'h')
            for (int j = 0; j < m->n_ranges; j++) {
                plcrt_range_t *w = &m->ranges[j];
                if (w->dev == r->dev && w->is_write && w->table == 'h' && w->policy == POLICY_TRIGGER &&
                    w->pending && w->req_unit == r->req_unit && w->req_len >= 1 && w->req_len <= 121 &&
                    w->req_len <= w->size) {
                    pair = j;
                    q->waddr = w->req_addr;
                    q->wcount = w->req_len;
                    memcpy(q->wdata, w->req, sizeof q->wdata[0] * (size_t)w->req_len);
                    break;
                }
            }
        munlock(m);
        if (!go) continue;
        q->fc = pair >= 0 ? 23 : function_code(r);
        q->addr = r->policy == POLICY_TRIGGER ? r->req_addr : r->start;
        q->status_first = r->status_first;
        q->extra_req = q->extra_rsp = 0;
        int status;
        if (q->unit < 0 || q->unit > 255) {
            /* unit_id = %QWn held a value that is no unit id: the request is not sent */
            mlock(m);
            d->n_errors++;
            munlock(m);
            log_limited(rt, d, LOG_UNIT, now, "device %s: unit id %d from %%QW%d out of range (0..255): request of range %s not sent",
                        d->name, q->unit, d->unit_word, r->name);
            status = STATUS_TRANSPORT(EINVAL);
        } else if (q->addr + q->count > 65536 && q->count <= r->size) {
            /* the address word puts the request past Modbus address 65535: not sent */
            mlock(m);
            d->n_errors++;
            munlock(m);
            log_limited(rt, d, LOG_LENGTH, now, "range %s: address %d + %d registers runs past 65535",
                        r->name, q->addr, q->count);
            status = STATUS_TRANSPORT(EINVAL);
        } else if (q->count < 1 || q->count > r->size) {
            /* the length word asks for more than the range has */
            mlock(m);
            d->n_errors++;
            munlock(m);
            log_limited(rt, d, LOG_LENGTH, now, "range %s: length word %%QW%d = %d is outside 1..%d",
                        r->name, r->length, q->count, r->size);
            status = STATUS_TRANSPORT(EINVAL);
        } else if (line) {
            /* on the wire from now on; the answer comes in a later step */
            if (line_start(rt, m, line, r, q, now, pair) == 0) {
                m->line_rr = i + 1;
                line_advance(rt, m, line, now);
                continue;
            }
            status = STATUS_TRANSPORT(ENOMEM);
        } else {
            status = range_request(rt, m, r, q, now);
            if (status < 0) continue; /* skipped: device in reconnect backoff */
        }
        publish(m, r, q, status);
        if (pair >= 0) publish(m, &m->ranges[pair], q, status);
    }
    /* nothing on a line and nothing pending: the real-time master thread goes to sleep, and
     * its next pass starts at the first range again (config order), so the next round here
     * does too (a write listed before its read then goes first, as in real time) */
    int idle = !plcrt_threaded(rt); /* (line_rr is for virtual time only) */
    for (int i = 0; i < m->n_devices && idle; i++)
        idle = m->devices[i].line_range < 0;
    for (int i = 0; i < m->n_ranges && idle; i++)
        idle = !m->ranges[i].pending;
    if (idle) m->line_rr = 0;
}

void plcrt_master_step(plcrt_t *rt, struct plcrt_master *m, uint64_t now) { step(rt, m, now, 0); }

/* ------------------------------------------------------------------ real-time thread */

static void *master_thread(void *arg)
{
    struct plcrt_master *m = arg;
    pthread_mutex_lock(&m->lock);
    while (!m->stop) {
        pthread_mutex_unlock(&m->lock);
        uint64_t now = plcrt_monotonic_ns();
        plcrt_master_step(m->rt, m, now);
        pthread_mutex_lock(&m->lock);
        /* sleep until the next range is due, a trigger edge, or stop */
        uint64_t wake = now + 1000000000ull;
        int pending = 0;
        for (int i = 0; i < m->n_ranges; i++) {
            plcrt_range_t *r = &m->ranges[i];
            if (r->pending) pending = 1;
            if (r->policy != POLICY_TRIGGER && r->next_due < wake) wake = r->next_due;
        }
        if (pending || m->stop) continue;
        struct timespec ts = {(time_t)(wake / 1000000000ull), (long)(wake % 1000000000ull)};
        pthread_cond_timedwait(&m->wake, &m->lock, &ts);
    }
    pthread_mutex_unlock(&m->lock);
    return NULL;
}

int plcrt_master_start_thread(plcrt_t *rt, struct plcrt_master *m)
{
    if (m->thread_running || m->n_ranges == 0) return 0;
    /* next_due values of earlier virtual scans mean nothing on the monotonic clock */
    uint64_t now = plcrt_monotonic_ns();
    for (int i = 0; i < m->n_ranges; i++) m->ranges[i].next_due = now;
    for (int i = 0; i < m->n_devices; i++) m->devices[i].next_connect_ns = 0;
    m->stop = 0;
    plcrt_master_note_lines(rt, m);
    if (pthread_create(&m->thread, NULL, master_thread, m) != 0) {
        plcrt_seterr(rt, "cannot start the Modbus master thread");
        return -1;
    }
    m->thread_running = 1;
    return 0;
}

void plcrt_master_stop_thread(struct plcrt_master *m)
{
    if (!m || !m->thread_running) return;
    pthread_mutex_lock(&m->lock);
    m->stop = 1;
    pthread_cond_signal(&m->wake);
    pthread_mutex_unlock(&m->lock);
    pthread_join(m->thread, NULL);
    m->thread_running = 0;
}

void plcrt_master_flush(plcrt_t *rt, struct plcrt_master *m, uint64_t now)
{
    /* the outputs of the last scan reach the devices even if their period had not come */
    mlock(m);
    for (int i = 0; i < m->n_ranges; i++)
        if (m->ranges[i].is_write && m->ranges[i].policy != POLICY_TRIGGER) m->ranges[i].next_due = 0;
    munlock(m);
    step(rt, m, now, 1);
}

/* ------------------------------------------------------------------ public API */

int plcrt_device_set_fd(plcrt_t *rt, const char *device, int fd, plcrt_after_send_fn after_send,
                        void *user)
{
    struct plcrt_master *m = rt->master;
    if (rt->started) {
        plcrt_seterr(rt, "plcrt_device_set_fd: call before the first scan");
        return -1;
    }
    for (int i = 0; m && i < m->n_devices; i++) {
        plcrt_device_t *d = &m->devices[i];
        if (strcmp(d->name, device) != 0) continue;
        if (fd < 0) {
            plcrt_seterr(rt, "plcrt_device_set_fd: bad fd %d", fd);
            return -1;
        }
        if (d->ctx) {
            if (d->ext_fd >= 0) modbus_set_socket(d->ctx, -1);
            else modbus_close(d->ctx);
            modbus_free(d->ctx);
            d->ctx = NULL;
        }
        d->ext_fd = fd;
        d->transact = NULL;
        d->after_send = after_send;
        d->after_send_user = user;
        return device_ensure_ctx(rt, d);
    }
    plcrt_seterr(rt, "no device '%s' in the config", device);
    return -1;
}

int plcrt_device_set_transport(plcrt_t *rt, const char *device, plcrt_transact_fn transact,
                               void *user)
{
    struct plcrt_master *m = rt->master;
    if (rt->started) {
        plcrt_seterr(rt, "plcrt_device_set_transport: call before the first scan");
        return -1;
    }
    if (!transact) {
        plcrt_seterr(rt, "plcrt_device_set_transport: no handler");
        return -1;
    }
    for (int i = 0; m && i < m->n_devices; i++) {
        plcrt_device_t *d = &m->devices[i];
        if (strcmp(d->name, device) != 0) continue;
        if (d->ctx) {
            if (d->ext_fd >= 0) modbus_set_socket(d->ctx, -1);
            else modbus_close(d->ctx);
            modbus_free(d->ctx);
            d->ctx = NULL;
        }
        d->ext_fd = -1;
        d->after_send = NULL;
        d->transact = transact;
        d->transact_user = user;
        d->connected = 1;
        return 0;
    }
    plcrt_seterr(rt, "no device '%s' in the config", device);
    return -1;
}

int plcrt_device_count(const plcrt_t *rt) { return rt->master ? rt->master->n_devices : 0; }

const char *plcrt_device_name(const plcrt_t *rt, int i)
{
    if (!rt->master || i < 0 || i >= rt->master->n_devices) return NULL;
    return rt->master->devices[i].name;
}

int plcrt_device_stats(const plcrt_t *rt, int i, uint64_t *errors, uint64_t *requests,
                       uint64_t *connects)
{
    if (!rt->master || i < 0 || i >= rt->master->n_devices) return -1;
    struct plcrt_master *m = rt->master;
    pthread_mutex_lock(&m->lock);
    const plcrt_device_t *d = &m->devices[i];
    if (errors) *errors = d->n_errors;
    if (requests) *requests = d->n_requests;
    if (connects) *connects = d->n_connects;
    pthread_mutex_unlock(&m->lock);
    return 0;
}

uint64_t plcrt_device_dropped_replies(const plcrt_t *rt, int i)
{
    if (!rt->master || i < 0 || i >= rt->master->n_devices) return 0;
    struct plcrt_master *m = rt->master;
    pthread_mutex_lock(&m->lock);
    uint64_t n = m->devices[i].n_stale;
    pthread_mutex_unlock(&m->lock);
    return n;
}
