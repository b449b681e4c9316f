/* Internal structures shared by the core's files (not installed). */
#ifndef PLCRT_INTERNAL_H
#define PLCRT_INTERNAL_H

#include "plcrt.h"
#include <pthread.h>
#include <stdarg.h>

#define PLCRT_MAX_FORCES 256

typedef struct plcrt_force_entry {
    void *addr;
    size_t size;
    unsigned char value[16];
} plcrt_force_entry_t;

struct plcrt_master; /* plcrt_master.c */
struct plcrt_slave;  /* plcrt_slave.c */

/* Field order: what every scan reads first, the image, forces and the error text last (an idle
 * scan then touches a few cache lines of the runtime besides the image cells it uses). */
struct plcrt {
    const plcrt_program_t *prog;
    uint64_t tick_ns;
    uint64_t tick;      /* number of the next config_run__ tick */
    uint64_t time_ns;   /* virtual (or elapsed, in real-time mode) time */
    int started;        /* first scan done: config is frozen */
    plcrt_mode_t mode;
    struct plcrt_master *master;
    struct plcrt_slave *slave;
    size_t n_forces;
    plcrt_rt_stats_t stats;
    char *retain_path;          /* plcrt_retain_set_file */
    uint64_t retain_period_ns;
    uint64_t retain_last_ns;    /* scan time of the last save */
    uint64_t retain_saves;      /* snapshots completed since plcrt_new ([retain] saved) */
    uint64_t retain_failures;   /* failed saves since plcrt_new */
    uint64_t retain_unlogged;   /* failed saves not reported yet (rate limit) */
    uint64_t retain_log_ns;     /* scan time of the last failure line */
    int retain_failing;         /* the last save failed */
    int retain_request;         /* [retain] request: flat %QX bit index, -1 = none */
    int retain_saved;           /* [retain] saved: %IW index, -1 = none */
    int slave_watch;            /* [slave] watch: holding address whose writes are counted, -1 = none */
    int slave_watch_count;      /* [slave] watch_count: %IW index of the count, -1 = none */
    int retain_mem;             /* snapshots go to retain_buf (plcrt_retain_set_memory) */
    uint8_t *retain_buf;        /* the last complete in-memory snapshot */
    size_t retain_len;          /* its length; 0 = none yet */
    plcrt_log_fn log_fn;
    void *log_user;
    pthread_mutex_t image_lock; /* held while the program or an exchange touches the image */
    plcrt_force_entry_t forces[PLCRT_MAX_FORCES];
    char err[512];
    plcrt_image_t img;
};

/* Locking of the state the real-time threads share with the scan (image_lock, the master's
 * lock). Only real-time mode has other threads - the master and slave threads, started by
 * plcrt_run_realtime after it set the mode, which never goes back - so a virtual (stepped) run,
 * one thread by definition, takes no mutex at all: the co-simulation scans hundreds of PLCs per
 * tick. Functions of the public API that other threads may call (stats, retain files) lock
 * always. */
static inline int plcrt_threaded(const plcrt_t *rt) { return rt->mode == PLCRT_REALTIME; }
static inline void plcrt_lock(const plcrt_t *rt, pthread_mutex_t *mu)
{
    if (plcrt_threaded(rt)) pthread_mutex_lock(mu);
}
static inline void plcrt_unlock(const plcrt_t *rt, pthread_mutex_t *mu)
{
    if (plcrt_threaded(rt)) pthread_mutex_unlock(mu);
}

/* Before the program of every scan (the caller holds image_lock): writes [retain] saved. */
void plcrt_retain_before_scan(plcrt_t *rt);
/* After each scan (the caller does not hold image_lock): takes a snapshot when one is due -
 * the period of scan time has passed or the program set [retain] request - to the file or to
 * memory. The one place that decides; plcrt_scan and plcrt_run_realtime both call it. */
void plcrt_retain_tick(plcrt_t *rt);

void plcrt_seterr(plcrt_t *rt, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void plcrt_log(plcrt_t *rt, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
uint64_t plcrt_monotonic_ns(void);

/* Master (plcrt_master.c). The config parser builds it; the scan loop drives it. */
int plcrt_master_parse(plcrt_t *rt, const char *name, const char *text, struct plcrt_master **out);
void plcrt_master_free(struct plcrt_master *m);
/* image → master (outputs, trigger edges); called with image_lock held. Returns 0 when no
 * request can be due (no trigger request pending, no cycle/change range): plcrt_master_step
 * would do nothing. */
int plcrt_master_exchange_out(plcrt_t *rt, struct plcrt_master *m);
/* master → image (read data, done/error/status, counters); image_lock held */
void plcrt_master_exchange_in(plcrt_t *rt, struct plcrt_master *m);
/* performs the requests that are due at time now_ns (virtual or monotonic) */
void plcrt_master_step(plcrt_t *rt, struct plcrt_master *m, uint64_t now_ns);
/* writes the cycle/change ranges now (end of a real-time run) */
void plcrt_master_flush(plcrt_t *rt, struct plcrt_master *m, uint64_t now_ns);
/* at start: says once what the serial lines cannot carry (a pty's parity) */
void plcrt_master_note_lines(plcrt_t *rt, struct plcrt_master *m);
int plcrt_master_start_thread(plcrt_t *rt, struct plcrt_master *m);
void plcrt_master_stop_thread(struct plcrt_master *m);
int plcrt_master_is_empty(const struct plcrt_master *m);

/* Slave (plcrt_slave.c) */
void plcrt_slave_free(struct plcrt_slave *s);
int plcrt_slave_start_thread(plcrt_t *rt);
void plcrt_slave_stop_thread(plcrt_t *rt);
/* Answers one complete Modbus TCP ADU (MBAP + PDU) into reply (260 bytes); its length, or
 * -1 when the MBAP header is not Modbus TCP. lock: take image_lock for the copy. */
int plcrt_slave_process_adu(plcrt_t *rt, const uint8_t *adu, size_t len, uint8_t *reply, int lock);


#endif
