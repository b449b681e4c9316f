/* Internal: the Modbus master's configuration and state (plcrt_config.c builds it,
 * plcrt_master.c runs it). */
#ifndef PLCRT_MASTER_H
#define PLCRT_MASTER_H

#include "plcrt_internal.h"

#include <modbus.h>

#define PLCRT_NAME_MAX 64
#define PLCRT_MAX_BITS 2000 /* FC1/FC2 limit; the largest range kind */
#define PLCRT_LOG_INTERVAL_NS 60000000000ull /* at most one line per device and kind per 60 s */

enum { POLICY_CYCLE, POLICY_CHANGE, POLICY_TRIGGER };
enum { RESULT_NONE, RESULT_OK, RESULT_ERROR };

typedef struct plcrt_range {
    char name[PLCRT_NAME_MAX];
    int line;
    int is_write;
    char table;      /* 'h' holding, 'i' input registers, 'c' coils, 'd' discrete inputs */
    int start, size; /* Modbus address and count */
    int image;       /* first word index (%IW/%QW), or flat bit index a*8+b (%IX/%QX) */
    int policy;
    int trigger, done, error; /* flat bit indexes, -1 = none */
    int status, length;       /* word indexes, -1 = none */
    int dev;

    /* state; guarded by the master's lock */
    uint16_t out[PLCRT_MAX_BITS];  /* outputs as of the last exchange (regs or 0/1 bits) */
    uint16_t req[PLCRT_MAX_BITS];  /* data of the trigger request (snapshot at the edge) */
    uint16_t last[PLCRT_MAX_BITS]; /* last successfully written (change policy) */
    uint16_t in[PLCRT_MAX_BITS];   /* data read, waiting for the next exchange */
    int have_last;
    int fresh;           /* in[] holds new data */
    int req_len;
    int req_unit;        /* unit id of the trigger request (sampled at the edge; may be > 255) */
    int out_len;         /* length word as of the last exchange (size without one) */
    int out_unit;        /* unit id as of the last exchange (cycle/change); -1 = none yet */
    uint64_t next_due;
    int trig_level;      /* trigger bit as of the last exchange */
    int pending;         /* a trigger edge waits for its request */
    int result;          /* RESULT_* of the trigger request, not yet shown */
    int status_value;
    int done_shown, error_shown;
} plcrt_range_t;

typedef struct plcrt_device {
    char name[PLCRT_NAME_MAX];
    int line;
    char host[256];
    int port, unit_id;
    int unit_word;   /* unit_id = %QWn: n, the unit id of each request is taken from it; -1 = constant */
    uint64_t timeout_ns, poll_ns;
    int errors_word; /* %IW index of the error counter, -1 = none */
    int online_bit;  /* flat %IX index, -1 = none */

    modbus_t *ctx;
    int connected;
    int ext_fd; /* >= 0: transport seam, an fd given by plcrt_device_set_fd */
    plcrt_after_send_fn after_send;
    void *after_send_user;
    plcrt_transact_fn transact; /* in-process transport (plcrt_device_set_transport) */
    void *transact_user;
    uint64_t next_connect_ns, backoff_ns;
    uint64_t n_errors, n_requests, n_connects;
    uint64_t n_stale; /* replies dropped: transaction id of an earlier request */
    uint16_t tid;     /* transaction id of the last request */
    int failing;     /* last request failed: log only transitions */
    /* rate limit of the transition lines (LOG_* in plcrt_master.c): one per kind and
     * PLCRT_LOG_INTERVAL_NS, the others counted and reported with the next one */
    uint64_t log_last_ns[5], log_suppressed[5];
    unsigned char log_seen[5];
    char last_error[160];
} plcrt_device_t;

struct plcrt_master {
    plcrt_device_t *devices;
    int n_devices;
    plcrt_range_t *ranges;
    int n_ranges;
    uint64_t reconnect_min_ns, reconnect_max_ns;
    int slave_enabled;
    char slave_host[256];
    int slave_port;
    uint64_t slave_idle_ns, slave_byte_ns; /* 0 = default */
    char retain_file[1024];                /* [retain] file; "" = none */
    uint64_t retain_period_ns;             /* [retain] period (default 1 s) */
    int retain_request;                    /* [retain] request: flat %QX bit index, -1 = none */
    int retain_saved;                      /* [retain] saved: %IW index, -1 = none */

    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_t thread;
    int thread_running;
    int stop;
    plcrt_t *rt;
};

#endif
