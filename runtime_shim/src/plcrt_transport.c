/* The master's transport and framing: a device's Modbus context (TCP, RTU, or an fd or in-process
 * handler given through the transport seam), connecting with backoff, the serial line's set-up
 * (parity a pty cannot keep), one request framed, sent and its answer checked
 * (plcrt_dev_request), and the rate-limited transition lines of a device. plcrt_master.c decides
 * which request goes when; plcrt_serial_line.c gives an RTU exchange its time on the wire in
 * virtual time. */
#include "plcrt_transport.h"

#include <errno.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <time.h>

/* ------------------------------------------------------------------ rate-limited log */

/* Logs a device's transition line unless one of the same kind was logged less than
 * PLCRT_LOG_INTERVAL_NS ago (time now: virtual or monotonic); suppressed lines are counted
 * and the count is appended to the next line of that kind. */
void plcrt_dev_log(plcrt_t *rt, plcrt_device_t *d, int kind, uint64_t now, const char *fmt, ...)
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

void plcrt_dev_close(plcrt_device_t *d)
{
    if (d->ctx && d->ext_fd < 0) modbus_close(d->ctx);
    d->connected = d->ext_fd >= 0;
}

int plcrt_dev_ensure_ctx(plcrt_t *rt, plcrt_device_t *d)
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
    return plcrt_dev_ensure_ctx(rt, d);
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
int plcrt_dev_connect(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *d, uint64_t now,
                          int *err)
{
    if (d->transact) return 0; /* in process: always there */
    if (d->rtu && d->bus != (int)(d - m->devices)) {
        /* a further device on a serial line: the line is the first device's */
        plcrt_device_t *o = &m->devices[d->bus];
        int rc = plcrt_dev_connect(rt, m, o, now, err);
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
    if ((d->rtu && d->ext_fd < 0 ? rtu_line_setup(rt, d) : plcrt_dev_ensure_ctx(rt, d)) != 0) {
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
            plcrt_dev_log(rt, d, LOG_CONNECTED, now, "device %s: reopened %s (closed after: %s)", d->name,
                        d->host, d->reopen_why);
        else if (d->n_connects > 1 || d->failing) {
            if (d->rtu)
                plcrt_dev_log(rt, d, LOG_CONNECTED, now, "device %s: opened %s", d->name, d->host);
            else
                plcrt_dev_log(rt, d, LOG_CONNECTED, now, "device %s: connected to %s:%d", d->name, d->host, d->port);
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


/* Frames unit id + PDU (n bytes) as a Modbus TCP ADU with the device's next transaction id
 * (never 0 after wrapping); returns the ADU length. One framing for TCP and in process. */
static int frame_adu(plcrt_device_t *d, const uint8_t *req, int n, uint8_t *adu)
{
    d->tid = (uint16_t)(d->tid + 1) ? (uint16_t)(d->tid + 1) : 1;
    plcrt_put16(adu, d->tid);
    plcrt_put16(adu + 2, 0);
    plcrt_put16(adu + 4, n);
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
        if (len < 2 || plcrt_get16(rsp) == tid) break;
        mlock(m);
        uint64_t n = ++d->n_stale;
        munlock(m);
        if (n == 1 || n % 100 == 0)
            plcrt_log(m->rt, "device %s: dropped a reply with transaction id %d, expected %d "
                      "(%llu dropped so far)", d->name, plcrt_get16(rsp), tid, (unsigned long long)n);
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
int plcrt_dev_request(struct plcrt_master *m, plcrt_device_t *d, request_t *q, int *transport)
{
    uint8_t req[MODBUS_TCP_MAX_ADU_LENGTH];
    uint8_t rsp[MODBUS_TCP_MAX_ADU_LENGTH + 64]; /* + room for an in-process handler's cap */
    int n = 0;
    *transport = 0;
    req[n++] = (uint8_t)q->unit; /* the request's own: unit_id = %QWn may change per request */
    req[n++] = (uint8_t)q->fc;
    plcrt_put16(req + n, q->addr); n += 2;
    plcrt_put16(req + n, q->count); n += 2;
    if (q->fc == 16) {
        req[n++] = (uint8_t)(q->count * 2);
        for (int i = 0; i < q->count; i++) { plcrt_put16(req + n, q->data[i]); n += 2; }
    } else if (q->fc == 23) {
        /* read address and quantity above, then the write part (written first by the slave) */
        plcrt_put16(req + n, q->waddr); n += 2;
        plcrt_put16(req + n, q->wcount); n += 2;
        req[n++] = (uint8_t)(q->wcount * 2);
        for (int i = 0; i < q->wcount; i++) { plcrt_put16(req + n, q->wdata[i]); n += 2; }
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
        if (len < h + 1 || len > MODBUS_TCP_MAX_ADU_LENGTH || plcrt_get16(rsp) != d->tid || plcrt_get16(rsp + 2) != 0 ||
            plcrt_get16(rsp + 4) != len - 6)
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
        for (int i = 0; i < q->count; i++) q->data[i] = (uint16_t)plcrt_get16(rsp + h + 2 + 2 * i);
    } else if (q->fc == 1 || q->fc == 2) {
        int bytes = (q->count + 7) / 8;
        if (rsp[h + 1] != bytes || len < h + 2 + bytes) goto bad;
        for (int i = 0; i < q->count; i++) q->data[i] = (rsp[h + 2 + i / 8] >> (i % 8)) & 1;
    } else {
        if (len < h + 5 || plcrt_get16(rsp + h + 1) != q->addr || plcrt_get16(rsp + h + 3) != q->count) goto bad;
    }
    return 0;
bad:
    /* a reply that does not fit the request: treat the stream as out of step */
    *transport = 1;
    return STATUS_TRANSPORT(EPROTO);
}

const char *plcrt_status_text(int status, char *buf, size_t n)
{
    if (status >= 1000) snprintf(buf, n, "%s", modbus_strerror(status - 1000));
    else snprintf(buf, n, "Modbus exception %d (%s)", status, modbus_strerror(MODBUS_ENOBASE + status));
    return buf;
}

