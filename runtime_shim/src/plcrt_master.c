/* Modbus master: which request goes when (policies cycle / change / trigger, a MIP read area's
 * status-first reads, errors and reconnects), the real-time thread, and the exchange with the
 * image. Data meet the image only in the exchange functions, which the scan loop calls between
 * scans. A request is framed, sent and checked in plcrt_transport.c (an MBAP frame with its own
 * transaction id, the transport seam's after_send hook, modbus_receive_confirmation); an RTU
 * exchange takes its time on the wire in virtual time in plcrt_serial_line.c. */
#include "plcrt_master.h"
#include "plcrt_serial_line.h"
#include "plcrt_transport.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static uint8_t *ix_bits(plcrt_t *rt) { return &rt->img.ix[0][0]; }
static uint8_t *qx_bits(plcrt_t *rt) { return &rt->img.qx[0][0]; }

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
 * blocks take a new number without bit 0 as a new record (MIP_Internal_ReadDecoder). Bit 0 alone cannot
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
    int status = plcrt_dev_request(m, d, q, transport);
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
        status = plcrt_dev_request(m, d, q, transport);
        if (status != 0) break;
        q->data[0] |= seen;
        if (want == size || 2 + q->data[1] <= want) break;
    }
    q->count = size;
    return status;
}

/* Performs one request of range r at time now; returns the status (0 = ok). */
int plcrt_range_request(plcrt_t *rt, struct plcrt_master *m, plcrt_range_t *r, request_t *q,
                         uint64_t now)
{
    plcrt_device_t *d = &m->devices[r->dev];
    int status, transport = 0, err;
    int exchanged = 0, rc = plcrt_dev_connect(rt, m, d, now, &err);
    if (rc != 0) {
        if (rc == -2 && r->policy != POLICY_TRIGGER)
            return -1; /* waiting for the reconnect backoff: no request, no error */
        status = STATUS_TRANSPORT(err);
        transport = 1;
    } else if (q->status_first) {
        status = status_first_request(m, d, r, q, &transport);
    } else {
        status = plcrt_dev_request(m, d, q, &transport);
    }
    exchanged = rc == 0;
    mlock(m); /* counters and state are read by the exchange */
    d->n_requests++;
    if (status != 0) d->n_errors++;
    munlock(m);
    if (status == 0) {
        if (d->rtu) m->devices[d->bus].line_fail_run = 0;
        if (d->failing)
            plcrt_dev_log(rt, d, LOG_RECOVERED, now, "device %s: requests succeed again (%llu errors so far)",
                        d->name, (unsigned long long)d->n_errors);
        d->failing = 0;
        return 0;
    }
    char why[160];
    plcrt_status_text(status, why, sizeof why);
    /* log transitions (and every 100th error), not every failed poll of a dead device */
    if (d->n_errors % 100 == 0)
        plcrt_log(rt, "device %s: %s %s %d+%d (range %s) failed: %s; %llu errors", d->name,
                  r->is_write ? "write" : "read",
                  r->table == 'h' ? "holding" : r->table == 'i' ? "input" : r->table == 'c' ? "coils" : "discrete",
                  q->addr, q->count, r->name, why, (unsigned long long)d->n_errors);
    else if (!d->failing)
        plcrt_dev_log(rt, d, LOG_FAILING, now, "device %s: %s %s %d+%d (range %s) failed: %s; %llu errors", d->name,
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
            plcrt_dev_close(o);
            munlock(m);
            o->line_fail_run = 0;
            o->backoff_ns = 0;
            o->next_connect_ns = now; /* at once: the next request opens it */
        }
    } else if (transport && d->connected && d->ext_fd < 0) {
        /* the TCP stream may hold a late answer: start over on a new connection */
        mlock(m);
        plcrt_dev_close(d);
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
void plcrt_range_publish(struct plcrt_master *m, plcrt_range_t *r, const request_t *q, int status)
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

/* A request that is not sent (its unit id, address or length word is out of range): an error of
 * its device, and a transport error EINVAL for the range's status. */
static int not_sent(struct plcrt_master *m, plcrt_device_t *d)
{
    mlock(m);
    d->n_errors++;
    munlock(m);
    return STATUS_TRANSPORT(EINVAL);
}

static void step(plcrt_t *rt, struct plcrt_master *m, uint64_t now, int writes_only)
{
    request_t *q = &m->q; /* large: not on the stack */
    /* virtual time: exchanges on serial lines move on first (they may finish now) */
    for (int i = 0; i < m->n_devices; i++) {
        plcrt_device_t *o = &m->devices[i];
        if (plcrt_line_modelled(rt, o) && o->bus == i) plcrt_line_advance(rt, m, o, now);
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
        plcrt_device_t *line = plcrt_line_modelled(rt, d) ? &m->devices[d->bus] : NULL;
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
            status = not_sent(m, d);
            plcrt_dev_log(rt, d, LOG_UNIT, now, "device %s: unit id %d from %%QW%d out of range (0..255): request of range %s not sent",
                        d->name, q->unit, d->unit_word, r->name);
        } else if (q->addr + q->count > 65536 && q->count <= r->size) {
            /* the address word puts the request past Modbus address 65535: not sent */
            status = not_sent(m, d);
            plcrt_dev_log(rt, d, LOG_LENGTH, now, "range %s: address %d + %d registers runs past 65535",
                        r->name, q->addr, q->count);
        } else if (q->count < 1 || q->count > r->size) {
            /* the length word asks for more than the range has */
            status = not_sent(m, d);
            plcrt_dev_log(rt, d, LOG_LENGTH, now, "range %s: length word %%QW%d = %d is outside 1..%d",
                        r->name, r->length, q->count, r->size);
        } else if (line) {
            /* on the wire from now on; the answer comes in a later step */
            if (plcrt_line_start(rt, m, line, r, q, now, pair) == 0) {
                m->line_rr = i + 1;
                plcrt_line_advance(rt, m, line, now);
                continue;
            }
            status = STATUS_TRANSPORT(ENOMEM);
        } else {
            status = plcrt_range_request(rt, m, r, q, now);
            if (status < 0) continue; /* skipped: device in reconnect backoff */
        }
        plcrt_range_publish(m, r, q, status);
        if (pair >= 0) plcrt_range_publish(m, &m->ranges[pair], q, status);
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
        return plcrt_dev_ensure_ctx(rt, d);
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
