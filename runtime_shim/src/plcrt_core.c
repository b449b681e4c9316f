/* The scan loop: I/O phase → forces → program → forces → advance time by the tick. */
#include "plcrt_master.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

void plcrt_seterr(plcrt_t *rt, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(rt->err, sizeof rt->err, fmt, ap);
    va_end(ap);
}

static void default_log(void *user, const char *line)
{
    (void)user;
    fprintf(stderr, "plcrt: %s\n", line);
}

void plcrt_log(plcrt_t *rt, const char *fmt, ...)
{
    char line[600];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (rt->log_fn) rt->log_fn(rt->log_user, line);
}

void plcrt_set_log(plcrt_t *rt, plcrt_log_fn fn, void *user)
{
    rt->log_fn = fn;
    rt->log_user = user;
}

uint64_t plcrt_monotonic_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

plcrt_t *plcrt_new(const plcrt_program_t *prog, char *err, size_t errlen)
{
    if (!prog || !prog->init || !prog->run || !prog->ticktime_ns || !prog->current_time) {
        snprintf(err, errlen, "program does not provide the ABI (config_init__, config_run__, common_ticktime__)");
        return NULL;
    }
    if (*prog->ticktime_ns == 0) {
        snprintf(err, errlen, "program has common_ticktime__ = 0: no task with an INTERVAL?");
        return NULL;
    }
    plcrt_t *rt = calloc(1, sizeof *rt);
    if (!rt) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    rt->prog = prog;
    rt->tick_ns = *prog->ticktime_ns;
    rt->log_fn = default_log;
    rt->retain_request = rt->retain_saved = -1;
    rt->slave_watch = rt->slave_watch_count = -1;
    pthread_mutex_init(&rt->image_lock, NULL);
    if (prog->bind && prog->bind(&rt->img, err, errlen) != 0) {
        free(rt);
        return NULL;
    }
    prog->current_time->tv_sec = 0;
    prog->current_time->tv_nsec = 0;
    prog->init();
    return rt;
}

void plcrt_free(plcrt_t *rt)
{
    if (!rt) return;
    plcrt_slave_stop_thread(rt);
    if (rt->master) plcrt_master_stop_thread(rt->master);
    plcrt_master_free(rt->master);
    plcrt_slave_free(rt->slave);
    pthread_mutex_destroy(&rt->image_lock);
    free(rt->retain_path);
    free(rt->retain_buf);
    free(rt);
}

const char *plcrt_errmsg(const plcrt_t *rt) { return rt->err; }
plcrt_image_t *plcrt_image(plcrt_t *rt) { return &rt->img; }
uint64_t plcrt_time_ns(const plcrt_t *rt) { return rt->time_ns; }
uint64_t plcrt_tick_ns(const plcrt_t *rt) { return rt->tick_ns; }
uint64_t plcrt_scan_count(const plcrt_t *rt) { return rt->stats.scans; }

int plcrt_force(plcrt_t *rt, void *addr, const void *value, size_t size)
{
    if (!addr || size == 0 || size > sizeof rt->forces[0].value) {
        plcrt_seterr(rt, "force: bad address or size %zu", size);
        return -1;
    }
    size_t i;
    for (i = 0; i < rt->n_forces; i++)
        if (rt->forces[i].addr == addr) break;
    if (i == rt->n_forces) {
        if (rt->n_forces == PLCRT_MAX_FORCES) {
            plcrt_seterr(rt, "force: more than %d forced variables", PLCRT_MAX_FORCES);
            return -1;
        }
        rt->n_forces++;
    }
    rt->forces[i].addr = addr;
    rt->forces[i].size = size;
    memcpy(rt->forces[i].value, value, size);
    memcpy(addr, value, size); /* visible at once, like a write */
    return 0;
}

int plcrt_unforce(plcrt_t *rt, void *addr)
{
    for (size_t i = 0; i < rt->n_forces; i++) {
        if (rt->forces[i].addr == addr) {
            rt->forces[i] = rt->forces[--rt->n_forces];
            return 0;
        }
    }
    plcrt_seterr(rt, "unforce: not forced");
    return -1;
}

static void apply_forces(plcrt_t *rt)
{
    for (size_t i = 0; i < rt->n_forces; i++)
        memcpy(rt->forces[i].addr, rt->forces[i].value, rt->forces[i].size);
}

size_t plcrt_symbol_count(const plcrt_t *rt) { return rt->prog->n_symbols; }
/* (symbol_addr is only called for i < n_symbols, which is 0 without a symbol table) */
const char *plcrt_symbol_name(const plcrt_t *rt, size_t i)
{
    return i < rt->prog->n_symbols ? rt->prog->symbol_names[i] : NULL;
}
void *plcrt_symbol_addr(const plcrt_t *rt, size_t i)
{
    return i < rt->prog->n_symbols ? rt->prog->symbol_addr(i) : NULL;
}

static void set_current_time(plcrt_t *rt)
{
    rt->prog->current_time->tv_sec = (long)(rt->time_ns / 1000000000ull);
    rt->prog->current_time->tv_nsec = (long)(rt->time_ns % 1000000000ull);
}

/* The program part of a scan; the caller holds image_lock. */
static void run_program(plcrt_t *rt)
{
    if (rt->retain_saved >= 0) plcrt_retain_before_scan(rt);
    apply_forces(rt);
    set_current_time(rt);
    rt->prog->run((unsigned long)rt->tick);
    apply_forces(rt);
}

int plcrt_scan(plcrt_t *rt, uint64_t n)
{
    if (rt->mode == PLCRT_REALTIME && rt->started) {
        plcrt_seterr(rt, "plcrt_scan: the runtime is in real-time mode");
        return -1;
    }
    if (!rt->started && rt->master) plcrt_master_note_lines(rt, rt->master);
    rt->started = 1;
    for (uint64_t i = 0; i < n; i++) {
        if (rt->slave) plcrt_slave_poll(rt, 0);
        plcrt_lock(rt, &rt->image_lock); /* virtual mode: no other thread, no mutex */
        if (rt->master) {
            /* an idle scan of trigger ranges (none pending): nothing for step to do */
            if (plcrt_master_exchange_out(rt, rt->master))
                plcrt_master_step(rt, rt->master, rt->time_ns);
            plcrt_master_exchange_in(rt, rt->master);
        }
        run_program(rt);
        plcrt_unlock(rt, &rt->image_lock);
        rt->tick++;
        rt->time_ns += rt->tick_ns;
        rt->stats.scans++;
        plcrt_retain_tick(rt);
    }
    set_current_time(rt);
    return 0;
}

static void add_ns(struct timespec *ts, uint64_t ns)
{
    uint64_t t = (uint64_t)ts->tv_nsec + ns;
    ts->tv_sec += (time_t)(t / 1000000000ull);
    ts->tv_nsec = (long)(t % 1000000000ull);
}

static uint64_t ts_ns(const struct timespec *ts)
{
    return (uint64_t)ts->tv_sec * 1000000000ull + (uint64_t)ts->tv_nsec;
}

int plcrt_run_realtime(plcrt_t *rt, uint64_t max_scans, volatile int *stop)
{
    if (rt->started && rt->mode != PLCRT_REALTIME) {
        plcrt_seterr(rt, "plcrt_run_realtime: virtual scans already ran");
        return -1;
    }
    rt->mode = PLCRT_REALTIME;
    rt->started = 1;
    if (rt->master && plcrt_master_start_thread(rt, rt->master) != 0) return -1;
    if (rt->slave && plcrt_slave_start_thread(rt) != 0) return -1;
    struct timespec deadline;
    clock_gettime(CLOCK_MONOTONIC, &deadline);
    uint64_t t0 = ts_ns(&deadline);
    for (uint64_t i = 0; (max_scans == 0 || i < max_scans) && !(stop && *stop); i++) {
        uint64_t start = plcrt_monotonic_ns();
        uint64_t due = ts_ns(&deadline);
        if (start > due) {
            uint64_t late = start - due;
            if (late > rt->stats.max_late_ns) rt->stats.max_late_ns = late;
        }
        pthread_mutex_lock(&rt->image_lock);
        if (rt->master)
            plcrt_master_exchange_in(rt, rt->master);
        rt->time_ns = due - t0;
        run_program(rt);
        /* Outputs and trigger edges go to the master thread as soon as the scan ends (as a
         * PLC writes its output image), so a request raised in scan k is done in the idle time
         * after it and its result is in the image of scan k+1: the same scan-level timing as
         * virtual time. Exchanging at the start of the next scan cost one scan per request. */
        if (rt->master)
            plcrt_master_exchange_out(rt, rt->master);
        pthread_mutex_unlock(&rt->image_lock);
        rt->tick++;
        rt->stats.scans++;
        plcrt_retain_tick(rt);
        uint64_t end = plcrt_monotonic_ns();
        if (end - start > rt->stats.max_scan_ns) rt->stats.max_scan_ns = end - start;
        add_ns(&deadline, rt->tick_ns);
        if (end > ts_ns(&deadline)) {
            /* Overrun: the scan ended after the next deadline. Skip the missed
             * deadlines rather than running a burst of late scans. */
            rt->stats.overruns++;
            if (rt->stats.overruns == 1 || rt->stats.overruns % 1000 == 0)
                plcrt_log(rt, "overrun: scan %llu took %.3f ms of a %.3f ms tick (%llu overruns so far)",
                          (unsigned long long)rt->stats.scans, (end - start) / 1e6,
                          rt->tick_ns / 1e6, (unsigned long long)rt->stats.overruns);
            while (ts_ns(&deadline) < end) {
                add_ns(&deadline, rt->tick_ns);
                rt->tick++;
            }
        }
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, NULL) == EINTR)
            if (stop && *stop) break;
    }
    rt->time_ns = ts_ns(&deadline) - t0;
    if (rt->master) plcrt_master_stop_thread(rt->master);
    plcrt_flush_outputs(rt);
    plcrt_slave_stop_thread(rt);
    return 0;
}

int plcrt_flush_outputs(plcrt_t *rt)
{
    if (!rt->master) return 0;
    if (rt->master->thread_running) {
        plcrt_seterr(rt, "plcrt_flush_outputs: the real-time run is still going");
        return -1;
    }
    plcrt_lock(rt, &rt->image_lock);
    plcrt_master_exchange_out(rt, rt->master);
    plcrt_unlock(rt, &rt->image_lock);
    plcrt_master_flush(rt, rt->master,
                       rt->mode == PLCRT_REALTIME ? plcrt_monotonic_ns() : rt->time_ns);
    return 0;
}

void plcrt_rt_stats(const plcrt_t *rt, plcrt_rt_stats_t *out) { *out = rt->stats; }

int plcrt_load_config_text(plcrt_t *rt, const char *name, const char *text)
{
    if (rt->started) {
        plcrt_seterr(rt, "%s: error: config must be loaded before the first scan", name);
        return -1;
    }
    struct plcrt_master *m = NULL;
    if (plcrt_master_parse(rt, name, text, &m) != 0) return -1;
    plcrt_master_free(rt->master);
    rt->master = m;
    if (m->retain_file[0]) plcrt_retain_set_file(rt, m->retain_file, m->retain_period_ns);
    rt->retain_request = m->retain_request;
    rt->retain_saved = m->retain_saved;
    rt->slave_watch = m->slave_watch;
    rt->slave_watch_count = m->slave_watch_count;
    if (m->slave_enabled && !rt->slave &&
        plcrt_slave_start(rt, m->slave_host, m->slave_port) != 0) {
        char why[sizeof rt->err];
        snprintf(why, sizeof why, "%s", rt->err);
        plcrt_seterr(rt, "%s: error: [slave]: %s", name, why);
        return -1;
    }
    if (m->slave_enabled &&
        plcrt_slave_set_timeouts(rt, m->slave_idle_ns ? m->slave_idle_ns : PLCRT_SLAVE_IDLE_TIMEOUT_NS,
                                 m->slave_byte_ns ? m->slave_byte_ns : PLCRT_SLAVE_BYTE_TIMEOUT_NS) != 0)
        return -1;
    return 0;
}

int plcrt_load_config_mem(plcrt_t *rt, const char *name, const void *data, size_t len)
{
    if (len > PLCRT_CONFIG_MAX) {
        plcrt_seterr(rt, "%s: error: larger than %d bytes: not a config file", name, PLCRT_CONFIG_MAX);
        return -1;
    }
    const char *nul = memchr(data, 0, len);
    if (nul) {
        int line = 1;
        for (const char *c = data; c < nul; c++) line += *c == '\n';
        plcrt_seterr(rt, "%s:%d: error: NUL byte: not a text file", name, line);
        return -1;
    }
    char *buf = malloc(len + 1);
    if (!buf) {
        plcrt_seterr(rt, "%s: error: out of memory", name);
        return -1;
    }
    memcpy(buf, data, len);
    buf[len] = 0;
    int rc = plcrt_load_config_text(rt, name, buf);
    free(buf);
    return rc;
}

int plcrt_load_config(plcrt_t *rt, const char *path)
{
    /* O_NONBLOCK: opening a FIFO must not wait for a writer; only regular files are read */
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) {
        plcrt_seterr(rt, "%s: error: cannot open: %s", path, strerror(errno));
        return -1;
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        plcrt_seterr(rt, "%s: error: cannot stat: %s", path, strerror(errno));
        close(fd);
        return -1;
    }
    if (!S_ISREG(st.st_mode)) {
        plcrt_seterr(rt, "%s: error: %s, not a config file", path,
                     S_ISDIR(st.st_mode) ? "a directory" : "not a regular file");
        close(fd);
        return -1;
    }
    if (st.st_size > PLCRT_CONFIG_MAX) {
        plcrt_seterr(rt, "%s: error: larger than %d bytes (%lld): not a config file", path,
                     PLCRT_CONFIG_MAX, (long long)st.st_size);
        close(fd);
        return -1;
    }
    /* read at most one byte past the limit: a file that grows meanwhile is still refused */
    char *buf = malloc(PLCRT_CONFIG_MAX + 1);
    if (!buf) {
        plcrt_seterr(rt, "%s: error: out of memory", path);
        close(fd);
        return -1;
    }
    size_t len = 0;
    for (;;) {
        ssize_t got = read(fd, buf + len, PLCRT_CONFIG_MAX + 1 - len);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) {
            plcrt_seterr(rt, "%s: error: cannot read: %s", path, strerror(errno));
            free(buf);
            close(fd);
            return -1;
        }
        if (got == 0 || (len += (size_t)got) > PLCRT_CONFIG_MAX) break;
    }
    close(fd);
    int rc = plcrt_load_config_mem(rt, path, buf, len);
    free(buf);
    return rc;
}
