/* RETAIN: snapshots of the retained variables (core: to / from a buffer; thin file layer:
 * new file, fsync, rename, so the previous snapshot stays valid until the rename). */
#include "plcrt_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAGIC "PLCRTRT1"
#define VERSION 1u
#define HEADER (8 + 4 + 8 + 4)

static uint32_t crc32(const uint8_t *p, size_t n)
{
    uint32_t c = 0xffffffffu;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return ~c;
}

static void put32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static void put64(uint8_t *p, uint64_t v) { for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i)); }
static uint32_t get32(const uint8_t *p) { uint32_t v = 0; for (int i = 3; i >= 0; i--) v = v << 8 | p[i]; return v; }
static uint64_t get64(const uint8_t *p) { uint64_t v = 0; for (int i = 7; i >= 0; i--) v = v << 8 | p[i]; return v; }

size_t plcrt_retain_count(const plcrt_t *rt)
{
    const plcrt_program_t *p = rt->prog;
    return p->retain_addr && p->retain_size && p->retain_names ? p->n_retain : 0;
}

static size_t payload_size(const plcrt_t *rt)
{
    size_t n = 0;
    for (size_t i = 0; i < plcrt_retain_count(rt); i++) n += rt->prog->retain_size(i);
    return n;
}

static uint64_t fnv(uint64_t h, const void *data, size_t n)
{
    const uint8_t *p = data;
    for (size_t i = 0; i < n; i++) { h ^= p[i]; h *= 0x100000001b3ull; }
    return h;
}

/* Identifies the set of retained variables: a program with other names, types or sizes
 * has another hash, and its snapshot is not restored. */
static uint64_t layout_hash(const plcrt_t *rt)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < plcrt_retain_count(rt); i++) {
        const char *name = rt->prog->retain_names[i];
        const char *type = rt->prog->retain_types ? rt->prog->retain_types[i] : "";
        uint64_t size = rt->prog->retain_size(i);
        h = fnv(h, name, strlen(name) + 1);
        h = fnv(h, type, strlen(type) + 1);
        h = fnv(h, &size, sizeof size);
    }
    return h;
}

size_t plcrt_retain_snapshot_size(const plcrt_t *rt) { return HEADER + payload_size(rt) + 4; }

size_t plcrt_retain_save_to(plcrt_t *rt, void *buf, size_t cap)
{
    size_t need = plcrt_retain_snapshot_size(rt), pay = payload_size(rt);
    if (cap < need) {
        plcrt_seterr(rt, "retain: a snapshot needs %zu bytes, the buffer has %zu", need, cap);
        return 0;
    }
    if (pay > 0xffffffffu) {
        plcrt_seterr(rt, "retain: %zu bytes of retained variables is too much", pay);
        return 0;
    }
    uint8_t *b = buf;
    memcpy(b, MAGIC, 8);
    put32(b + 8, VERSION);
    put64(b + 12, layout_hash(rt));
    put32(b + 20, (uint32_t)pay);
    size_t off = HEADER;
    for (size_t i = 0; i < plcrt_retain_count(rt); i++) {
        size_t n = rt->prog->retain_size(i);
        memcpy(b + off, rt->prog->retain_addr(i), n);
        off += n;
    }
    put32(b + off, crc32(b, off));
    return off + 4;
}

int plcrt_retain_load_from(plcrt_t *rt, const void *buf, size_t len)
{
    const uint8_t *b = buf;
    if (len < HEADER + 4 || memcmp(b, MAGIC, 8) != 0) {
        plcrt_seterr(rt, "not a plcrt retain snapshot%s", len < HEADER + 4 ? " (too short)" : "");
        return -1;
    }
    if (get32(b + 8) != VERSION) {
        plcrt_seterr(rt, "retain snapshot version %u, this runtime reads %u", get32(b + 8), VERSION);
        return -1;
    }
    uint64_t pay = get32(b + 20);
    if (len != HEADER + pay + 4) {
        plcrt_seterr(rt, "retain snapshot truncated or padded: %zu bytes, expected %llu", len,
                     (unsigned long long)(HEADER + pay + 4));
        return -1;
    }
    if (crc32(b, HEADER + pay) != get32(b + HEADER + pay)) {
        plcrt_seterr(rt, "retain snapshot checksum mismatch (corrupt)");
        return -1;
    }
    if (get64(b + 12) != layout_hash(rt) || pay != payload_size(rt)) {
        plcrt_seterr(rt, "retain snapshot is of another set of retained variables (program changed)");
        return -1;
    }
    size_t off = HEADER;
    for (size_t i = 0; i < plcrt_retain_count(rt); i++) {
        size_t n = rt->prog->retain_size(i);
        memcpy(rt->prog->retain_addr(i), b + off, n);
        off += n;
    }
    return 0;
}

static int write_all(int fd, const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t w = write(fd, p, n);
        if (w < 0) {
            if (errno == EINTR) continue;
            return -1;
        }
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

int plcrt_retain_save_file(plcrt_t *rt, const char *path)
{
    size_t cap = plcrt_retain_snapshot_size(rt);
    uint8_t *buf = malloc(cap);
    if (!buf) { plcrt_seterr(rt, "retain: out of memory"); return -1; }
    pthread_mutex_lock(&rt->image_lock);
    size_t len = plcrt_retain_save_to(rt, buf, cap);
    pthread_mutex_unlock(&rt->image_lock);
    if (!len) { free(buf); return -1; }
    size_t pl = strlen(path);
    char *tmp = malloc(pl + 5), *dir = malloc(pl + 1);
    if (!tmp || !dir) { free(buf); free(tmp); free(dir); plcrt_seterr(rt, "retain: out of memory"); return -1; }
    memcpy(tmp, path, pl);
    memcpy(tmp + pl, ".tmp", 5);
    int rc = -1;
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
        plcrt_seterr(rt, "retain: %s: %s", tmp, strerror(errno));
        goto out;
    }
    if (write_all(fd, buf, len) != 0 || fsync(fd) != 0) {
        plcrt_seterr(rt, "retain: %s: %s", tmp, strerror(errno));
        close(fd);
        unlink(tmp);
        goto out;
    }
    close(fd);
    if (rename(tmp, path) != 0) {
        plcrt_seterr(rt, "retain: rename %s: %s", path, strerror(errno));
        unlink(tmp);
        goto out;
    }
    memcpy(dir, path, pl + 1);
    int dfd = open(dirname(dir), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) { fsync(dfd); close(dfd); }
    rt->retain_saves++;
    rc = 0;
out:
    free(buf);
    free(tmp);
    free(dir);
    return rc;
}

int plcrt_retain_load_file(plcrt_t *rt, const char *path)
{
    rt->err[0] = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        if (errno != ENOENT) plcrt_seterr(rt, "%s: %s", path, strerror(errno));
        return 0;
    }
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        plcrt_seterr(rt, "%s: not a regular file", path);
        close(fd);
        return 0;
    }
    size_t want = plcrt_retain_snapshot_size(rt);
    if ((uint64_t)st.st_size != want) {
        plcrt_seterr(rt, "%s: %lld bytes, a snapshot of this program has %zu (truncated, "
                     "foreign, or the program changed)", path, (long long)st.st_size, want);
        close(fd);
        return 0;
    }
    uint8_t *buf = malloc(want);
    size_t got = 0;
    while (buf && got < want) {
        ssize_t r = read(fd, buf + got, want - got);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) break;
        got += (size_t)r;
    }
    close(fd);
    if (!buf || got != want) {
        plcrt_seterr(rt, "%s: short read", path);
        free(buf);
        return 0;
    }
    char why[512];
    pthread_mutex_lock(&rt->image_lock);
    int rc = plcrt_retain_load_from(rt, buf, want);
    pthread_mutex_unlock(&rt->image_lock);
    free(buf);
    if (rc != 0) {
        snprintf(why, sizeof why, "%s", rt->err);
        plcrt_seterr(rt, "%s: %s", path, why);
        return 0;
    }
    return 1;
}

/* A failing save is logged at once, then at most once a minute of scan time with the count:
 * a program that keeps its request up retries every scan, and a full disk must not flood the
 * log. */
#define RETAIN_LOG_INTERVAL_NS 60000000000ull

void plcrt_retain_set_file(plcrt_t *rt, const char *path, uint64_t period_ns)
{
    free(rt->retain_path);
    rt->retain_path = path ? strdup(path) : NULL;
    if (path) rt->retain_mem = 0;
    rt->retain_period_ns = period_ns;
    rt->retain_last_ns = rt->time_ns;
}

int plcrt_retain_set_memory(plcrt_t *rt, uint64_t period_ns)
{
    if (!rt->retain_buf) {
        rt->retain_buf = malloc(plcrt_retain_snapshot_size(rt));
        if (!rt->retain_buf) {
            plcrt_seterr(rt, "retain: out of memory");
            return -1;
        }
        rt->retain_len = 0;
    }
    free(rt->retain_path);
    rt->retain_path = NULL;
    rt->retain_mem = 1;
    rt->retain_period_ns = period_ns;
    rt->retain_last_ns = rt->time_ns;
    return 0;
}

size_t plcrt_retain_last(plcrt_t *rt, void *buf, size_t cap)
{
    if (!rt->retain_mem || rt->retain_len == 0) {
        plcrt_seterr(rt, "retain: no snapshot in memory yet");
        return 0;
    }
    if (cap < rt->retain_len) {
        plcrt_seterr(rt, "retain: a snapshot needs %zu bytes, the buffer has %zu", rt->retain_len, cap);
        return 0;
    }
    memcpy(buf, rt->retain_buf, rt->retain_len);
    return rt->retain_len;
}

static int save_memory(plcrt_t *rt)
{
    plcrt_lock(rt, &rt->image_lock);
    size_t len = plcrt_retain_save_to(rt, rt->retain_buf, plcrt_retain_snapshot_size(rt));
    plcrt_unlock(rt, &rt->image_lock);
    if (!len) return -1;
    rt->retain_len = len;
    rt->retain_saves++;
    return 0;
}

/* one snapshot to wherever they go (file or memory); 0 or -1 with plcrt_errmsg */
static int save_now(plcrt_t *rt)
{
    return rt->retain_mem ? save_memory(rt) : plcrt_retain_save_file(rt, rt->retain_path);
}

void plcrt_retain_before_scan(plcrt_t *rt)
{
    if (rt->retain_saved >= 0) rt->img.iw[rt->retain_saved] = (uint16_t)rt->retain_saves;
}

void plcrt_retain_tick(plcrt_t *rt)
{
    if (!rt->retain_path && !rt->retain_mem) return;
    int requested = 0;
    if (rt->retain_request >= 0) {
        plcrt_lock(rt, &rt->image_lock);
        requested = rt->img.qx[rt->retain_request / 8][rt->retain_request % 8] != 0;
        plcrt_unlock(rt, &rt->image_lock);
    }
    int periodic = rt->retain_period_ns != 0 &&
                   rt->time_ns - rt->retain_last_ns >= rt->retain_period_ns;
    if (!requested && !periodic) return;
    /* any snapshot restarts the period: it is as recent as a periodic one */
    rt->retain_last_ns = rt->time_ns;
    if (save_now(rt) == 0) {
        if (rt->retain_failing)
            plcrt_log(rt, "retain: saving again (%llu failed saves in all)",
                      (unsigned long long)rt->retain_failures);
        rt->retain_failing = 0;
        rt->retain_unlogged = 0;
        return;
    }
    rt->retain_failures++;
    rt->retain_unlogged++;
    if (!rt->retain_failing || rt->time_ns - rt->retain_log_ns >= RETAIN_LOG_INTERVAL_NS) {
        plcrt_log(rt, "%s (%llu failed saves%s; [retain] saved does not change until a save succeeds)",
                  rt->err, (unsigned long long)rt->retain_failures,
                  rt->retain_unlogged > 1 ? ", the others since the last line not logged" : "");
        rt->retain_log_ns = rt->time_ns;
        rt->retain_unlogged = 0;
    }
    rt->retain_failing = 1;
}

int plcrt_retain_stop(plcrt_t *rt)
{
    if (!rt->retain_path && !rt->retain_mem) return 0;
    return save_now(rt);
}

uint64_t plcrt_retain_saves(const plcrt_t *rt) { return rt->retain_saves; }
uint64_t plcrt_retain_failures(const plcrt_t *rt) { return rt->retain_failures; }
int plcrt_retain_handshake(const plcrt_t *rt) { return rt->retain_request >= 0 || rt->retain_saved >= 0; }
const char *plcrt_retain_file(const plcrt_t *rt) { return rt->retain_path; }
uint64_t plcrt_retain_period_ns(const plcrt_t *rt) { return rt->retain_period_ns; }
