/* Internal: the master's transport and framing (plcrt_transport.c). */
#ifndef PLCRT_TRANSPORT_H
#define PLCRT_TRANSPORT_H

#include "plcrt_master.h"

/* the status of a request that failed in transport: 1000 + errno (a Modbus exception is 1..255) */
#define STATUS_TRANSPORT(e) (1000 + ((e) > 0 && (e) < 64000 ? (e) : EPROTO))

static inline void plcrt_put16(uint8_t *p, int v) { p[0] = (uint8_t)(v >> 8); p[1] = (uint8_t)v; }
static inline int plcrt_get16(const uint8_t *p) { return (p[0] << 8) | p[1]; }

/* the kinds of a device's transition lines, each rate-limited on its own */
enum { LOG_CONNECTED, LOG_FAILING, LOG_RECOVERED, LOG_LENGTH, LOG_UNIT };

/* Logs a device's transition line unless one of the same kind was logged less than
 * PLCRT_LOG_INTERVAL_NS ago (time now: virtual or monotonic); suppressed lines are counted
 * and the count is appended to the next line of that kind. */
void plcrt_dev_log(plcrt_t *rt, plcrt_device_t *d, int kind, uint64_t now, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

/* the device's libmodbus context, made at the first use (an fd of the transport seam: set on it) */
int plcrt_dev_ensure_ctx(plcrt_t *rt, plcrt_device_t *d);

/* closes the device's connection (a transport-seam fd stays: it is the caller's) */
void plcrt_dev_close(plcrt_device_t *d);

/* 0 when connected; -1 with the errno to report; -2 while waiting for the reconnect backoff
 * (*err: the error of the last attempt, or ENOTCONN after a failed request closed it) */
int plcrt_dev_connect(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *d, uint64_t now, int *err);

/* One request over the device's transport. Returns 0, or the status for the program:
 * a Modbus exception code 1..255, or 1000+errno for transport errors (then *transport = 1). */
int plcrt_dev_request(struct plcrt_master *m, plcrt_device_t *d, request_t *q, int *transport);

/* a status of plcrt_dev_request as text, into buf */
const char *plcrt_status_text(int status, char *buf, size_t n);

#endif
