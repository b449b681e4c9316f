/* Internal: the Modbus master's configuration and state (plcrt_config.c builds it,
 * plcrt_master.c runs it, through plcrt_transport.c and plcrt_serial_line.c). */
#ifndef PLCRT_MASTER_H
#define PLCRT_MASTER_H

#include "plcrt_internal.h"

#include <modbus.h>

#define PLCRT_NAME_MAX 64
#define PLCRT_MAX_BITS 2000 /* FC1/FC2 limit; the largest range kind */
#define PLCRT_LOG_INTERVAL_NS 60000000000ull /* at most one line per device and kind per 60 s */
/* a serial line is closed and opened again (and so configured again) after an error of the
 * operating system on it (EIO of a tty that went away, ...) at once, and after this many
 * exchanges on it failed in a row (timeouts, bad answers): the settings of the tty may have been
 * changed beneath us (our choice; no manual speaks of it) */
#define PLCRT_SERIAL_REOPEN_AFTER 3

enum { POLICY_CYCLE, POLICY_CHANGE, POLICY_TRIGGER };
enum { RESULT_NONE, RESULT_OK, RESULT_ERROR };

/* Field order: what every scan reads (the policy, the handshake cells, the state) first, names
 * and the large buffers last, so that an idle scan touches one or two cache lines per range
 * and device (the co-simulation scans hundreds of PLCs per tick, each with its own copies). */
typedef struct plcrt_range {
    int policy;
    int is_write;
    char table;      /* 'h' holding, 'i' input registers, 'c' coils, 'd' discrete inputs */
    int start, size; /* Modbus address and count */
    int image;       /* first word index (%IW/%QW), or flat bit index a*8+b (%IX/%QX) */
    int trigger, done, error; /* flat bit indexes, -1 = none */
    int status, length;       /* word indexes, -1 = none */
    int address;              /* trigger: %QW word index of the request's first address, -1 = start */
    int status_first;         /* reads: registers of the MIP read area's first read (status, count,
                               * maybe data; plcrt_master.c), 0 = the whole range every time */
    int dev;
    int line;

    /* state; guarded by the master's lock (real-time mode) */
    int trig_level;      /* trigger bit as of the last exchange */
    int pending;         /* a trigger edge waits for its request */
    int result;          /* RESULT_* of the trigger request, not yet shown */
    int status_value;
    int done_shown, error_shown;
    int have_last;
    int fresh;           /* in[] holds new data */
    int have_in;         /* in[] holds a read of this run (status_first: a whole block) */
    int req_len;
    int req_addr;        /* first Modbus address of the trigger request (sampled at the edge) */
    int req_unit;        /* unit id of the trigger request (sampled at the edge; may be > 255) */
    int out_len;         /* cycle/change: length word as of the last exchange (size without one) */
    int out_unit;        /* unit id as of the last exchange (cycle/change); -1 = none yet */
    uint64_t next_due;

    char name[PLCRT_NAME_MAX];
    uint16_t out[PLCRT_MAX_BITS];  /* cycle/change: outputs as of the last exchange (regs or 0/1 bits) */
    uint16_t req[PLCRT_MAX_BITS];  /* trigger: data of the request (taken from the image at the edge) */
    uint16_t last[PLCRT_MAX_BITS]; /* last successfully written (change policy) */
    uint16_t in[PLCRT_MAX_BITS];   /* data read, waiting for the next exchange */
} plcrt_range_t;

typedef struct plcrt_device {
    int errors_word; /* %IW index of the error counter, -1 = none */
    int online_bit;  /* flat %IX index, -1 = none */
    int connected;
    int port, unit_id;
    int unit_word;   /* unit_id = %QWn: n, the unit id of each request is taken from it; -1 = constant */
    uint64_t n_errors, n_requests, n_connects;
    uint64_t n_stale; /* replies dropped: transaction id of an earlier request */
    uint64_t timeout_ns, poll_ns;
    int line;

    modbus_t *ctx;
    int ext_fd; /* >= 0: transport seam, an fd given by plcrt_device_set_fd */
    plcrt_after_send_fn after_send;
    void *after_send_user;
    plcrt_transact_fn transact; /* in-process transport (plcrt_device_set_transport) */
    void *transact_user;
    uint64_t next_connect_ns, backoff_ns;
    uint16_t tid;     /* transaction id of the last request */
    int failing;     /* last request failed: log only transitions */
    /* rate limit of the transition lines (LOG_* in plcrt_transport.h): one per kind and
     * PLCRT_LOG_INTERVAL_NS, the others counted and reported with the next one */
    uint64_t log_last_ns[5], log_suppressed[5];
    unsigned char log_seen[5];
    char name[PLCRT_NAME_MAX];
    char host[256];   /* TCP: host; RTU: the serial line's path */
    char last_error[160];
    /* Modbus RTU (serial = PATH instead of host): libmodbus's RTU backend; devices on the same
     * line share the first one's context (bus) and take the line in turn */
    int rtu;
    int fc23;              /* a pending trigger read and write of this device go as one FC23 */
    int baud, data_bits, stop_bits;
    char parity;           /* 'N', 'E', 'O' */
    uint64_t pause_ns;     /* silence before each request on the line (OpenPLC's RTU_TX_Pause) */
    char line_parity;      /* owner: the parity the line is opened with: parity, or 'N' on a line
                            * that carries none (a pty; a tty that dropped PARENB), 0 = not decided */
    int line_fail_run;     /* owner: exchanges on the line that failed in a row (reopen after
                            * PLCRT_SERIAL_REOPEN_AFTER) */
    int connect_err;       /* errno of the last failed attempt to connect / open, 0 after a success */
    char reopen_why[160];  /* the failure that closed the line, for the "reopened" line; "" = none */
    int line_no_parity;    /* owner: the tty dropped PARENB or refused it (EINVAL): open without */
    int line_noted;        /* owner: the line's missing parity has been logged (once) */
    int bus;               /* index of the device that owns the line's context (itself or an earlier one) */
    uint64_t bus_free_ns;  /* owner: monotonic time the line's last exchange ended */
    /* virtual time (owner of the line): the exchange on the wire, modelled from the character
     * time, so a co-simulation pays the line's time (plcrt_serial_line.c, "serial line in virtual
     * time"); line_range < 0 = the line is idle */
    struct request *line_req; /* the request on the line (allocated at the first use) */
    int line_range;        /* its range */
    int line_range2;       /* FC23: the write range that goes with it, -1 = none */
    int line_phase;        /* 1: the request is on the wire, 2: the answer is */
    int line_status;       /* phase 2: the result */
    uint64_t line_send_ns; /* phase 1: its last character reaches the slave */
    uint64_t line_done_ns; /* phase 2: the answer's last character reaches the master */
    uint64_t line_free_ns; /* the next request may start (a 3.5-character gap after the answer) */
    uint64_t line_busy_ns; /* total virtual time the line carried exchanges (statistics) */
} plcrt_device_t;

/* One request being built and done (step() in plcrt_master.c) */
typedef struct request {
    int fc, addr, count;
    int status_first;  /* registers of the first read of a MIP read area (range option), 0 = off */
    int extra_req, extra_rsp; /* characters of the follow-up exchanges status_first made */
    int waddr, wcount;        /* FC23: the write part (fc 23; addr/count are the read part) */
    uint16_t wdata[128];
    int unit; /* unit id of this request (0..255 by the time it is sent) */
    uint16_t data[PLCRT_MAX_BITS]; /* write data in, read data out */
} request_t;

struct plcrt_master {
    plcrt_device_t *devices;
    int n_devices;
    plcrt_range_t *ranges;
    int n_ranges;
    plcrt_t *rt;
    int thread_running;
    int stop;
    uint64_t reconnect_min_ns, reconnect_max_ns;
    int slave_enabled;
    char slave_host[256];
    int slave_port;
    uint64_t slave_idle_ns, slave_byte_ns; /* 0 = default */
    int slave_watch;                       /* [slave] watch: holding address, -1 = none */
    int slave_watch_count;                 /* [slave] watch_count: %IW index, -1 = none */
    char retain_file[1024];                /* [retain] file; "" = none */
    uint64_t retain_period_ns;             /* [retain] period (default 1 s) */
    int retain_request;                    /* [retain] request: flat %QX bit index, -1 = none */
    int retain_saved;                      /* [retain] saved: %IW index, -1 = none */

    /* the request step() works on: one thread does the requests (the real-time master thread,
     * else the scanning thread), and a plain member, unlike a thread-local one, costs no
     * __tls_get_addr in a dlopen'ed libplc.so */
    request_t q;
    int line_rr; /* virtual time, serial lines: the range after the one that last took a line */

    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_t thread;
};

/* m->lock guards what the real-time master thread shares with the scan; in virtual mode there
 * is no such thread and no locking (plcrt_lock). */
static inline void mlock(struct plcrt_master *m) { plcrt_lock(m->rt, &m->lock); }
static inline void munlock(struct plcrt_master *m) { plcrt_unlock(m->rt, &m->lock); }

/* plcrt_master.c: range r's request q at time now (the status, 0 = ok; -1: no request, the
 * device waits for its reconnect backoff), and its result into the range for the next exchange */
int plcrt_range_request(plcrt_t *rt, struct plcrt_master *m, plcrt_range_t *r, request_t *q, uint64_t now);
void plcrt_range_publish(struct plcrt_master *m, plcrt_range_t *r, const request_t *q, int status);

#endif
