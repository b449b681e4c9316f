/* Config parser: the plcrt format (INI-like sections, see runtime_shim/README.md) or
 * OpenPLC's mbconfig.cfg. Every error is one line "FILE:LINE: error: ..." and nothing
 * is started before the whole file has been checked. */
#include "plcrt_master.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define MAX_DEVICES 64
#define MAX_RANGES 256

typedef struct parser {
    plcrt_t *rt;
    const char *file;
    struct plcrt_master *m;
    /* claims on the image to detect overlaps: line of the claiming key, 0 = free */
    int ix_claim[PLCRT_IMAGE_SIZE * 8];
    int iw_claim[PLCRT_IMAGE_SIZE];
    int qx_claim[PLCRT_IMAGE_SIZE * 8];
    int qw_claim[PLCRT_IMAGE_SIZE];
} parser_t;

static int perr(parser_t *p, int line, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int perr(parser_t *p, int line, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    plcrt_seterr(p->rt, "%s:%d: error: %s", p->file, line, msg);
    return -1;
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s)) s++;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1])) *--e = 0;
    return s;
}

static int parse_int(parser_t *p, int line, const char *key, const char *v, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long x = strtol(v, &end, 0);
    if (errno || end == v || *end)
        return perr(p, line, "%s: '%s' is not a number", key, v);
    if (x < lo || x > hi)
        return perr(p, line, "%s: %ld is out of range (%ld..%ld)", key, x, lo, hi);
    *out = x;
    return 0;
}

/* "100ms", "2s", "500us", "1.5s", or a bare number of milliseconds (OpenPLC's unit) */
static int parse_duration(parser_t *p, int line, const char *key, const char *v, uint64_t *out_ns)
{
    char *end;
    errno = 0;
    double x = strtod(v, &end);
    if (errno || end == v || x < 0)
        return perr(p, line, "%s: '%s' is not a duration (e.g. 100ms, 2s)", key, v);
    double scale;
    if (!*end || !strcmp(end, "ms")) scale = 1e6;
    else if (!strcmp(end, "s")) scale = 1e9;
    else if (!strcmp(end, "us")) scale = 1e3;
    else if (!strcmp(end, "ns")) scale = 1;
    else return perr(p, line, "%s: unknown unit in '%s' (ns, us, ms, s)", key, v);
    double ns = x * scale;
    if (ns > 3600e9) return perr(p, line, "%s: '%s' is longer than an hour", key, v);
    *out_ns = (uint64_t)ns;
    return 0;
}

/* address of a given area and size: returns word index or flat bit index */
static int parse_location(parser_t *p, int line, const char *key, const char *v, char want_area,
                          char want_size, int *out)
{
    char area, size;
    long parts[2];
    int n;
    if (plcrt_parse_address(v, &area, &size, parts, &n) != 0)
        return perr(p, line, "%s: bad address '%s' (expected e.g. %%%c%c%s)", key, v, want_area,
                    want_size, want_size == 'X' ? "100.0" : "100");
    if (area != want_area || size != want_size)
        return perr(p, line, "%s: '%s' must be a %%%c%c address", key, v, want_area, want_size);
    if (size == 'X') {
        if (n != 2 || parts[0] < 0 || parts[0] >= PLCRT_IMAGE_SIZE || parts[1] < 0 || parts[1] > 7)
            return perr(p, line, "%s: '%s' is outside the image (a.b with a < 1024, b < 8)", key, v);
        *out = (int)(parts[0] * 8 + parts[1]);
    } else {
        if (n != 1 || parts[0] < 0 || parts[0] >= PLCRT_IMAGE_SIZE)
            return perr(p, line, "%s: '%s' is outside the image (n < 1024)", key, v);
        *out = (int)parts[0];
    }
    return 0;
}

static const char *claim_name(char area, char size, int idx, char *buf, size_t n)
{
    if (size == 'X') snprintf(buf, n, "%%%cX%d.%d", area, idx / 8, idx % 8);
    else snprintf(buf, n, "%%%cW%d", area, idx);
    return buf;
}

/* mark count image cells as used by the key on line; overlaps are errors */
static int claim(parser_t *p, int line, char area, char size, int first, int count, const char *what)
{
    int *map, limit;
    if (area == 'I') { map = size == 'X' ? p->ix_claim : p->iw_claim; }
    else { map = size == 'X' ? p->qx_claim : p->qw_claim; }
    limit = size == 'X' ? PLCRT_IMAGE_SIZE * 8 : PLCRT_IMAGE_SIZE;
    char a[32], b[32];
    if (first + count > limit)
        return perr(p, line, "%s: %s..%s runs past the end of the image", what,
                    claim_name(area, size, first, a, sizeof a),
                    claim_name(area, size, first + count - 1, b, sizeof b));
    for (int i = first; i < first + count; i++) {
        if (map[i])
            return perr(p, line, "%s: %s overlaps what line %d uses", what,
                        claim_name(area, size, i, a, sizeof a), map[i]);
    }
    for (int i = first; i < first + count; i++) map[i] = line;
    return 0;
}

/* a one-cell location key (a handshake bit, a status or counter word): parsed, then claimed */
static int parse_claim_one(parser_t *p, int line, const char *key, const char *v, char area, char size,
                           int *out)
{
    if (parse_location(p, line, key, v, area, size, out)) return -1;
    return claim(p, line, area, size, *out, 1, key);
}

/* ------------------------------------------------------------------ plcrt format */

typedef enum { SEC_NONE, SEC_MASTER, SEC_SLAVE, SEC_DEVICE, SEC_READ, SEC_WRITE, SEC_RETAIN } section_t;

/* keys given in the current range section, by line (0 = absent) */
typedef struct range_keys {
    int line;
    char name[PLCRT_NAME_MAX];
    int is_write;
    int device, table, start, size, image, policy, trigger, done, error, status, length, address, status_first;
    char v_device[PLCRT_NAME_MAX], v_table[32], v_image[32], v_policy[32], v_trigger[32],
        v_done[32], v_error[32], v_status[32], v_length[32], v_address[32];
    long start_v, size_v;
    int status_first_v;
} range_keys_t;

typedef struct device_keys {
    int line;
    int host, port, unit_id, timeout, polling_period, errors, online;
    int serial, baud, parity, data_bits, stop_bits, pause, fc23;
} device_keys_t;

/* "none"/"even"/"odd" (also N/E/O and OpenPLC's None/Even/Odd) -> 'N'/'E'/'O', 0 = not one */
static char parity_of(const char *v)
{
    if (!strcasecmp(v, "none") || !strcasecmp(v, "n")) return 'N';
    if (!strcasecmp(v, "even") || !strcasecmp(v, "e")) return 'E';
    if (!strcasecmp(v, "odd") || !strcasecmp(v, "o")) return 'O';
    return 0;
}

/* RTU's character: 1 start, 8 data bits, parity, stop bits (MODBUS over Serial Line Specification
 * and Implementation Guide V1.02, section 2.5.1) */
#define RTU_8_BITS "Modbus RTU has 8 data bits (MODBUS over Serial Line V1.02, section 2.5.1)"

static int valid_baud(long b)
{
    static const long ok[] = {300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200,
                              230400, 460800, 921600};
    for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++)
        if (ok[i] == b) return 1;
    return 0;
}

/* RTU devices on the same line share the first one's context */
static void assign_bus(struct plcrt_master *m, plcrt_device_t *d)
{
    int self = (int)(d - m->devices);
    d->bus = self;
    d->line_range = d->line_range2 = -1;
    if (!d->rtu) return;
    for (int i = 0; i < self; i++)
        if (m->devices[i].rtu && !strcmp(m->devices[i].host, d->host)) {
            d->bus = i;
            return;
        }
}

/* devices sharing a line must agree on its settings */
static int check_bus(parser_t *p, plcrt_device_t *d)
{
    plcrt_device_t *o = &p->m->devices[d->bus];
    if (o == d) return 0;
    if (o->baud != d->baud || o->parity != d->parity || o->data_bits != d->data_bits ||
        o->stop_bits != d->stop_bits)
        return perr(p, d->line, "device %s: %s is also used by device %s (line %d) with other line settings",
                    d->name, d->host, o->name, o->line);
    return 0;
}

static int find_device(struct plcrt_master *m, const char *name)
{
    for (int i = 0; i < m->n_devices; i++)
        if (!strcmp(m->devices[i].name, name)) return i;
    return -1;
}

static int range_limit(const plcrt_range_t *r)
{
    if (r->table == 'c' || r->table == 'd') return r->is_write ? 1968 : 2000;
    return r->is_write ? 123 : 125;
}

static const char *table_name(char t)
{
    switch (t) {
    case 'h': return "holding";
    case 'i': return "input";
    case 'c': return "coils";
    default: return "discrete";
    }
}

/* checks a range section once it is complete and adds it */
static int finish_range(parser_t *p, range_keys_t *k, uint64_t default_poll)
{
    (void)default_poll;
    struct plcrt_master *m = p->m;
    const char *sec = k->is_write ? "write" : "read";
    if (!k->device) return perr(p, k->line, "[%s %s]: missing key 'device'", sec, k->name);
    if (!k->size) return perr(p, k->line, "[%s %s]: missing key 'size'", sec, k->name);
    if (!k->start) return perr(p, k->line, "[%s %s]: missing key 'start'", sec, k->name);
    if (!k->image) return perr(p, k->line, "[%s %s]: missing key 'image'", sec, k->name);
    if (m->n_ranges == MAX_RANGES) return perr(p, k->line, "more than %d ranges", MAX_RANGES);
    plcrt_range_t *r = &m->ranges[m->n_ranges];
    memset(r, 0, sizeof *r);
    snprintf(r->name, sizeof r->name, "%s", k->name);
    r->line = k->line;
    r->is_write = k->is_write;
    r->trigger = r->done = r->error = r->status = r->length = r->address = -1;
    r->dev = find_device(m, k->v_device);
    if (r->dev < 0)
        return perr(p, k->device, "device: no [device %s] above this range", k->v_device);
    /* -1: no poll before the first exchange (a write has no outputs of the program before it) */
    r->out_unit = m->devices[r->dev].unit_word >= 0 || r->is_write ? -1 : m->devices[r->dev].unit_id;
    /* table */
    r->table = 'h';
    if (k->table) {
        const char *t = k->v_table;
        if (!strcmp(t, "holding")) r->table = 'h';
        else if (!strcmp(t, "coils")) r->table = 'c';
        else if (!k->is_write && !strcmp(t, "input")) r->table = 'i';
        else if (!k->is_write && !strcmp(t, "discrete")) r->table = 'd';
        else
            return perr(p, k->table, "table: '%s' is not one of %s", t,
                        k->is_write ? "holding, coils" : "holding, input, coils, discrete");
    }
    r->start = (int)k->start_v;
    r->size = (int)k->size_v;
    int limit = range_limit(r);
    if (r->size < 1 || r->size > limit)
        return perr(p, k->size, "size: %d registers in one %s %s request (1..%d)", r->size,
                    table_name(r->table), k->is_write ? "write" : "read", limit);
    if (r->start + r->size > 65536)
        return perr(p, k->size, "start + size runs past Modbus address 65535");
    int bits = r->table == 'c' || r->table == 'd';
    char area = k->is_write ? 'Q' : 'I';
    if (parse_location(p, k->image, "image", k->v_image, area, bits ? 'X' : 'W', &r->image) != 0)
        return -1;
    /* policy */
    r->policy = POLICY_CYCLE;
    if (k->policy) {
        if (!strcmp(k->v_policy, "cycle")) r->policy = POLICY_CYCLE;
        else if (k->is_write && !strcmp(k->v_policy, "change")) r->policy = POLICY_CHANGE;
        else if (!strcmp(k->v_policy, "trigger")) r->policy = POLICY_TRIGGER;
        else
            return perr(p, k->policy, "policy: '%s' is not one of %s", k->v_policy,
                        k->is_write ? "cycle, change, trigger" : "cycle, trigger");
    }
    if (r->policy == POLICY_TRIGGER) {
        if (!k->trigger) return perr(p, k->line, "[%s %s]: policy trigger needs 'trigger'", sec, k->name);
        if (!k->done) return perr(p, k->line, "[%s %s]: policy trigger needs 'done'", sec, k->name);
        if (!k->error) return perr(p, k->line, "[%s %s]: policy trigger needs 'error'", sec, k->name);
        if (parse_location(p, k->trigger, "trigger", k->v_trigger, 'Q', 'X', &r->trigger) ||
            parse_location(p, k->done, "done", k->v_done, 'I', 'X', &r->done) ||
            parse_location(p, k->error, "error", k->v_error, 'I', 'X', &r->error))
            return -1;
        if (claim(p, k->trigger, 'Q', 'X', r->trigger, 1, "trigger") ||
            claim(p, k->done, 'I', 'X', r->done, 1, "done") ||
            claim(p, k->error, 'I', 'X', r->error, 1, "error"))
            return -1;
        if (k->status && parse_claim_one(p, k->status, "status", k->v_status, 'I', 'W', &r->status))
            return -1;
    } else {
        /* cycle / change: error and status show the last request's result (a poll that keeps
         * failing is seen by the program); trigger and done are the handshake's */
        int bad = k->trigger ? k->trigger : k->done;
        if (bad) return perr(p, bad, "trigger and done need policy = trigger");
        if (k->error && parse_claim_one(p, k->error, "error", k->v_error, 'I', 'X', &r->error))
            return -1;
        if (k->status && parse_claim_one(p, k->status, "status", k->v_status, 'I', 'W', &r->status))
            return -1;
    }
    if (k->length) {
        /* reads: only with policy trigger (a vendor client block's quantity, set per request) */
        if (!k->is_write && r->policy != POLICY_TRIGGER)
            return perr(p, k->length, "length: of a read range needs policy = trigger");
        if (bits) return perr(p, k->length, "length: only for register ranges");
        if (parse_claim_one(p, k->length, "length", k->v_length, 'Q', 'W', &r->length))
            return -1;
    }
    if (k->address) {
        /* the request's first address from the image, taken at the rising edge (a vendor
         * client block's address input); start/size stay the range the program may ask for */
        if (r->policy != POLICY_TRIGGER) return perr(p, k->address, "address: needs policy = trigger");
        if (parse_claim_one(p, k->address, "address", k->v_address, 'Q', 'W', &r->address))
            return -1;
    }
    if (k->status_first && k->status_first_v) {
        if (bits || r->size < 3)
            return perr(p, k->status_first, "status_first: for register reads of 3 or more (status, count, data)");
        if (k->status_first_v >= r->size)
            return perr(p, k->status_first, "status_first: %d registers first is the whole range (size %d): use no",
                        k->status_first_v, r->size);
        r->status_first = k->status_first_v;
    }
    if (claim(p, k->image, area, bits ? 'X' : 'W', r->image, r->size, "image")) return -1;
    /* two ranges of one device on the same registers are a mistake */
    for (int i = 0; i < m->n_ranges; i++) {
        plcrt_range_t *o = &m->ranges[i];
        if (o->dev == r->dev && o->is_write == r->is_write && o->table == r->table &&
            o->start < r->start + r->size && r->start < o->start + o->size)
            return perr(p, k->start, "%s %s %d..%d of device %s overlaps range '%s' (line %d)",
                        k->is_write ? "write" : "read", table_name(r->table), r->start,
                        r->start + r->size - 1, m->devices[r->dev].name, o->name, o->line);
    }
    m->n_ranges++;
    return 0;
}

static int set_str(parser_t *p, int line, const char *key, char *dst, size_t n, const char *v)
{
    if (strlen(v) >= n) return perr(p, line, "%s: value too long", key);
    memcpy(dst, v, strlen(v) + 1);
    return 0;
}

static int valid_name(const char *s)
{
    if (!*s) return 0;
    for (; *s; s++)
        if (!isalnum((unsigned char)*s) && *s != '_' && *s != '-' && *s != '.') return 0;
    return 1;
}

/* a device section is complete: a TCP host or a serial line, and keys that fit it */
static int finish_device(parser_t *p, plcrt_device_t *dev, const device_keys_t *dk)
{
    if (dk->host && dk->serial)
        return perr(p, dk->serial, "[device %s]: host and serial: a device is either Modbus TCP or RTU", dev->name);
    if (!dk->host && !dk->serial)
        return perr(p, dk->line, "[device %s]: missing key 'host' (Modbus TCP) or 'serial' (Modbus RTU)", dev->name);
    if (dk->host) {
        int bad = dk->baud ? dk->baud : dk->parity ? dk->parity : dk->data_bits ? dk->data_bits
                : dk->stop_bits ? dk->stop_bits : dk->pause;
        if (bad) return perr(p, bad, "baud, parity, data_bits, stop_bits and pause are keys of serial (RTU) devices");
    } else if (dk->port) {
        return perr(p, dk->port, "port is a key of TCP devices (this one has serial)");
    }
    /* "the use of no parity requires 2 stop bits" (MODBUS over Serial Line V1.02, section 2.5.1):
     * the default without parity; stop_bits = 1 when given is taken (many devices run 8N1) */
    if (dev->rtu && !dk->stop_bits && dev->parity == 'N') dev->stop_bits = 2;
    if (dev->rtu && dev->unit_word < 0 && dev->unit_id > 247)
        return perr(p, dk->unit_id, "unit_id: %d is not a Modbus RTU address (0..247)", dev->unit_id);
    assign_bus(p->m, dev);
    return check_bus(p, dev);
}

static int parse_plcrt(parser_t *p, char *text)
{
    struct plcrt_master *m = p->m;
    section_t sec = SEC_NONE;
    range_keys_t rk;
    device_keys_t dk;
    int master_seen = 0, slave_seen = 0, retain_seen = 0;
    int retain_keys[4] = {0}; /* file, period, request, saved */
    m->retain_period_ns = 1000000000ull;
    int master_keys[4] = {0};
    int slave_keys[6] = {0}; /* host, port, idle_timeout, byte_timeout, watch, watch_count */
    uint64_t default_poll = 100000000ull, default_timeout = 1000000000ull;
    memset(&rk, 0, sizeof rk);
    memset(&dk, 0, sizeof dk);
    plcrt_device_t *dev = NULL;
    int lineno = 0;
    char *save = NULL;
    /* strtok_r would merge empty lines and break line numbers: split by hand */
    char *cur = text;
    (void)save;
    int in_range = 0;
    while (cur) {
        char *nl = strchr(cur, '\n');
        if (nl) *nl = 0;
        char *line = cur;
        cur = nl ? nl + 1 : NULL;
        lineno++;
        char *hash = strchr(line, '#');
        if (hash) *hash = 0;
        char *s = trim(line);
        if (!*s) continue;
        if (*s == '[') {
            if (in_range && finish_range(p, &rk, default_poll)) return -1;
            in_range = 0;
            char *end = strchr(s, ']');
            if (!end || trim(end + 1)[0]) return perr(p, lineno, "section header must be [kind name]");
            *end = 0;
            char *kind = trim(s + 1);
            char *name = kind;
            while (*name && !isspace((unsigned char)*name)) name++;
            if (*name) *name++ = 0;
            name = trim(name);
            if (!strcmp(kind, "retain")) {
                if (*name) return perr(p, lineno, "[retain] takes no name");
                if (retain_seen) return perr(p, lineno, "[retain] given twice (first on line %d)", retain_seen);
                retain_seen = lineno;
                sec = SEC_RETAIN;
            } else if (!strcmp(kind, "master") || !strcmp(kind, "slave")) {
                if (*name) return perr(p, lineno, "[%s] takes no name", kind);
                int *seen = kind[0] == 'm' ? &master_seen : &slave_seen;
                if (*seen) return perr(p, lineno, "[%s] given twice (first on line %d)", kind, *seen);
                *seen = lineno;
                sec = kind[0] == 'm' ? SEC_MASTER : SEC_SLAVE;
                if (sec == SEC_SLAVE) {
                    m->slave_enabled = 1;
                    snprintf(m->slave_host, sizeof m->slave_host, "127.0.0.1");
                    m->slave_port = 502;
                }
            } else if (!strcmp(kind, "device") || !strcmp(kind, "read") || !strcmp(kind, "write")) {
                if (!valid_name(name))
                    return perr(p, lineno, "[%s NAME]: name missing or not made of letters, digits, _ - .", kind);
                if (strlen(name) >= PLCRT_NAME_MAX) return perr(p, lineno, "name too long");
                if (kind[0] == 'd') {
                    if (dev && finish_device(p, dev, &dk)) return -1;
                    if (find_device(m, name) >= 0) return perr(p, lineno, "device '%s' defined twice", name);
                    if (m->n_devices == MAX_DEVICES) return perr(p, lineno, "more than %d devices", MAX_DEVICES);
                    dev = &m->devices[m->n_devices++];
                    memset(dev, 0, sizeof *dev);
                    snprintf(dev->name, sizeof dev->name, "%s", name);
                    dev->line = lineno;
                    dev->port = 502;
                    dev->unit_id = 1;
                    dev->unit_word = -1;
                    dev->timeout_ns = default_timeout;
                    dev->poll_ns = default_poll;
                    dev->errors_word = -1;
                    dev->online_bit = -1;
                    dev->ext_fd = -1;
                    dev->baud = 19200;
                    dev->data_bits = 8;
                    dev->stop_bits = 1;
                    dev->parity = 'N';
                    memset(&dk, 0, sizeof dk);
                    dk.line = lineno;
                    sec = SEC_DEVICE;
                } else {
                    for (int i = 0; i < m->n_ranges; i++)
                        if (!strcmp(m->ranges[i].name, name))
                            return perr(p, lineno, "range '%s' defined twice (line %d)", name, m->ranges[i].line);
                    memset(&rk, 0, sizeof rk);
                    rk.line = lineno;
                    rk.is_write = kind[0] == 'w';
                    snprintf(rk.name, sizeof rk.name, "%s", name);
                    in_range = 1;
                    sec = rk.is_write ? SEC_WRITE : SEC_READ;
                }
            } else {
                return perr(p, lineno, "unknown section [%s] (master, slave, device, read, write, retain)", kind);
            }
            continue;
        }
        char *eq = strchr(s, '=');
        if (!eq) return perr(p, lineno, "expected 'key = value' or [section]");
        *eq = 0;
        char *key = trim(s), *val = trim(eq + 1);
        if (!*val) return perr(p, lineno, "%s: missing value", key);
        /* quotes as in mbconfig.cfg are allowed */
        size_t vl = strlen(val);
        if (vl >= 2 && val[0] == '"' && val[vl - 1] == '"') { val[vl - 1] = 0; val++; }
        long x;
        int *slot = NULL;
        switch (sec) {
        case SEC_NONE:
            return perr(p, lineno, "key '%s' outside a section ([master], [device NAME], ...)", key);
        case SEC_MASTER:
            if (!strcmp(key, "polling_period")) {
                slot = &master_keys[0];
                if (parse_duration(p, lineno, key, val, &default_poll)) return -1;
                if (default_poll == 0) return perr(p, lineno, "polling_period must be > 0");
            } else if (!strcmp(key, "timeout")) {
                slot = &master_keys[1];
                if (parse_duration(p, lineno, key, val, &default_timeout)) return -1;
            } else if (!strcmp(key, "reconnect_min")) {
                slot = &master_keys[2];
                if (parse_duration(p, lineno, key, val, &m->reconnect_min_ns)) return -1;
            } else if (!strcmp(key, "reconnect_max")) {
                slot = &master_keys[3];
                if (parse_duration(p, lineno, key, val, &m->reconnect_max_ns)) return -1;
            } else
                return perr(p, lineno, "unknown key '%s' in [master] (polling_period, timeout, reconnect_min, reconnect_max)", key);
            if (m->n_devices > 0 && slot <= &master_keys[1])
                return perr(p, lineno, "%s: put [master] before the devices it is a default for", key);
            break;
        case SEC_RETAIN:
            if (!strcmp(key, "file")) {
                slot = &retain_keys[0];
                if (set_str(p, lineno, key, m->retain_file, sizeof m->retain_file, val)) return -1;
            } else if (!strcmp(key, "period")) {
                slot = &retain_keys[1];
                if (parse_duration(p, lineno, key, val, &m->retain_period_ns)) return -1;
            } else if (!strcmp(key, "request")) {
                /* the program's %QX bit: TRUE after a scan = a snapshot at the end of it */
                slot = &retain_keys[2];
                if (!retain_keys[2] && parse_claim_one(p, lineno, key, val, 'Q', 'X', &m->retain_request))
                    return -1;
            } else if (!strcmp(key, "saved")) {
                /* the runtime's %IW word: snapshots completed since the start, mod 65536 */
                slot = &retain_keys[3];
                if (!retain_keys[3] && parse_claim_one(p, lineno, key, val, 'I', 'W', &m->retain_saved))
                    return -1;
            } else
                return perr(p, lineno, "unknown key '%s' in [retain] (file, period, request, saved)", key);
            break;
        case SEC_SLAVE:
            if (!strcmp(key, "host")) {
                slot = &slave_keys[0];
                if (set_str(p, lineno, key, m->slave_host, sizeof m->slave_host, val)) return -1;
            } else if (!strcmp(key, "port")) {
                slot = &slave_keys[1];
                if (parse_int(p, lineno, key, val, 0, 65535, &x)) return -1;
                m->slave_port = (int)x;
            } else if (!strcmp(key, "idle_timeout") || !strcmp(key, "byte_timeout")) {
                int idle = key[0] == 'i';
                uint64_t *ns = idle ? &m->slave_idle_ns : &m->slave_byte_ns;
                slot = &slave_keys[idle ? 2 : 3];
                if (parse_duration(p, lineno, key, val, ns)) return -1;
                if (*ns == 0) return perr(p, lineno, "%s must be > 0", key);
            } else if (!strcmp(key, "watch")) {
                /* a holding register (%QW n = n, %MW n = 1024 + n) whose writes are counted */
                slot = &slave_keys[4];
                char area, size;
                long parts[2];
                int n;
                if (plcrt_parse_address(val, &area, &size, parts, &n) != 0 || size != 'W' ||
                    (area != 'Q' && area != 'M') || n != 1)
                    return perr(p, lineno, "watch: '%s' must be a %%QW or %%MW address (a holding register)", val);
                if (parts[0] < 0 || parts[0] >= PLCRT_IMAGE_SIZE)
                    return perr(p, lineno, "watch: '%s' is outside the image (n < 1024)", val);
                m->slave_watch = (int)parts[0] + (area == 'M' ? PLCRT_IMAGE_SIZE : 0);
            } else if (!strcmp(key, "watch_count")) {
                /* the runtime's %IW word: writes to the watched register since the start */
                slot = &slave_keys[5];
                if (!slave_keys[5] && parse_claim_one(p, lineno, key, val, 'I', 'W', &m->slave_watch_count))
                    return -1;
            } else
                return perr(p, lineno, "unknown key '%s' in [slave] (host, port, idle_timeout, byte_timeout, watch, watch_count)", key);
            break;
        case SEC_DEVICE:
            if (!strcmp(key, "host")) {
                slot = &dk.host;
                if (set_str(p, lineno, key, dev->host, sizeof dev->host, val)) return -1;
            } else if (!strcmp(key, "serial")) {
                slot = &dk.serial;
                if (set_str(p, lineno, key, dev->host, sizeof dev->host, val)) return -1;
                dev->rtu = 1;
            } else if (!strcmp(key, "baud")) {
                slot = &dk.baud;
                if (parse_int(p, lineno, key, val, 1, 4000000, &x)) return -1;
                if (!valid_baud(x)) return perr(p, lineno, "baud: %ld is not a standard rate (300 .. 921600)", x);
                dev->baud = (int)x;
            } else if (!strcmp(key, "parity")) {
                slot = &dk.parity;
                if (!(dev->parity = parity_of(val))) return perr(p, lineno, "parity: '%s' is not none, even or odd", val);
            } else if (!strcmp(key, "data_bits")) {
                slot = &dk.data_bits;
                if (parse_int(p, lineno, key, val, 5, 8, &x)) return -1;
                if (x != 8) return perr(p, lineno, "data_bits: %ld: " RTU_8_BITS, x);
                dev->data_bits = (int)x;
            } else if (!strcmp(key, "stop_bits")) {
                slot = &dk.stop_bits;
                if (parse_int(p, lineno, key, val, 1, 2, &x)) return -1;
                dev->stop_bits = (int)x;
            } else if (!strcmp(key, "fc23")) {
                slot = &dk.fc23;
                if (!strcmp(val, "yes") || !strcmp(val, "true")) dev->fc23 = 1;
                else if (!strcmp(val, "no") || !strcmp(val, "false")) dev->fc23 = 0;
                else return perr(p, lineno, "fc23: '%s' is not yes or no", val);
            } else if (!strcmp(key, "pause")) {
                slot = &dk.pause;
                if (parse_duration(p, lineno, key, val, &dev->pause_ns)) return -1;
            } else if (!strcmp(key, "port")) {
                slot = &dk.port;
                if (parse_int(p, lineno, key, val, 1, 65535, &x)) return -1;
                dev->port = (int)x;
            } else if (!strcmp(key, "unit_id")) {
                slot = &dk.unit_id;
                if (val[0] == '%' || isalpha((unsigned char)val[0])) {
                    /* unit_id = %QWn: the program chooses the unit id of each request */
                    if (!dk.unit_id && parse_claim_one(p, lineno, key, val, 'Q', 'W', &dev->unit_word))
                        return -1;
                } else {
                    if (parse_int(p, lineno, key, val, 0, 255, &x)) return -1;
                    dev->unit_id = (int)x;
                }
            } else if (!strcmp(key, "timeout")) {
                slot = &dk.timeout;
                if (parse_duration(p, lineno, key, val, &dev->timeout_ns)) return -1;
            } else if (!strcmp(key, "polling_period")) {
                slot = &dk.polling_period;
                if (parse_duration(p, lineno, key, val, &dev->poll_ns)) return -1;
                if (dev->poll_ns == 0) return perr(p, lineno, "polling_period must be > 0");
            } else if (!strcmp(key, "errors")) {
                slot = &dk.errors;
                if (parse_claim_one(p, lineno, key, val, 'I', 'W', &dev->errors_word))
                    return -1;
            } else if (!strcmp(key, "online")) {
                slot = &dk.online;
                if (parse_claim_one(p, lineno, key, val, 'I', 'X', &dev->online_bit))
                    return -1;
            } else
                return perr(p, lineno, "unknown key '%s' in [device] (host, port, serial, baud, parity, data_bits, stop_bits, pause, fc23, unit_id, timeout, polling_period, errors, online)", key);
            break;
        case SEC_READ:
        case SEC_WRITE:
#define RKEY(field, buf)                                                               \
    if (!strcmp(key, #field)) {                                                        \
        slot = &rk.field;                                                              \
        if (!*slot && set_str(p, lineno, key, rk.buf, sizeof rk.buf, val)) return -1;  \
        break;                                                                         \
    }
            do {
                RKEY(device, v_device)
                RKEY(table, v_table)
                RKEY(image, v_image)
                RKEY(policy, v_policy)
                RKEY(trigger, v_trigger)
                RKEY(done, v_done)
                RKEY(error, v_error)
                RKEY(status, v_status)
                RKEY(length, v_length)
                RKEY(address, v_address)
                if (sec == SEC_READ && !strcmp(key, "status_first")) {
                    slot = &rk.status_first;
                    char *end;
                    long v = strtol(val, &end, 10);
                    if (!strcmp(val, "yes") || !strcmp(val, "true")) rk.status_first_v = 2;
                    else if (!strcmp(val, "no") || !strcmp(val, "false")) rk.status_first_v = 0;
                    else if (end != val && !*end && v >= 2 && v <= 125) rk.status_first_v = (int)v;
                    else return perr(p, lineno, "status_first: '%s' is not yes, no or a count of registers 2..125", val);
                    break;
                }
                if (!strcmp(key, "start")) {
                    slot = &rk.start;
                    if (parse_int(p, lineno, key, val, 0, 65535, &rk.start_v)) return -1;
                    break;
                }
                if (!strcmp(key, "size")) {
                    slot = &rk.size;
                    if (parse_int(p, lineno, key, val, 0, 65536, &rk.size_v)) return -1;
                    break;
                }
                return perr(p, lineno, "unknown key '%s' in [%s] (device, table, start, size, image, policy, trigger, done, error, status, length, address%s)",
                            key, sec == SEC_WRITE ? "write" : "read", sec == SEC_WRITE ? "" : ", status_first");
            } while (0);
#undef RKEY
            break;
        }
        if (slot) {
            if (*slot) return perr(p, lineno, "key '%s' given twice (first on line %d)", key, *slot);
            *slot = lineno;
        }
    }
    if (in_range && finish_range(p, &rk, default_poll)) return -1;
    if (dev && finish_device(p, dev, &dk)) return -1;
    if (retain_seen && !retain_keys[0])
        return perr(p, retain_seen, "[retain]: missing key 'file'%s",
                    retain_keys[2] || retain_keys[3]
                        ? " (request and saved are about snapshots: they need somewhere to go)" : "");
    if (!slave_keys[4] != !slave_keys[5])
        return perr(p, slave_keys[4] ? slave_keys[4] : slave_keys[5],
                    "[slave]: watch and watch_count go together (the register and its write count)");
    (void)master_seen;
    return 0;
}

/* ------------------------------------------------------------------ mbconfig.cfg */

typedef struct mb_dev {
    int seen;
    int line;
    char name[PLCRT_NAME_MAX];
    char protocol[16];
    char address[256];
    long slave_id, port;
    char rtu_val[5][32]; /* RTU_Baud_Rate, _Parity, _Data_Bits, _Stop_Bits, _TX_Pause as given */
    int rtu_line[5];
    long start[5], size[5]; /* DI, coils, IR, HR read, HR write */
    int has[5 * 2 + 5];     /* lines of the keys given */
} mb_dev_t;

static const char *const mb_block[5] = {"Discrete_Inputs", "Coils", "Input_Registers",
                                        "Holding_Registers_Read", "Holding_Registers"};

int plcrt_config_is_mbconfig(const char *text);
int plcrt_config_is_mbconfig(const char *text)
{
    /* OpenPLC's file has no [sections] and starts its keys with Num_Devices / deviceN. */
    const char *s = text;
    while (*s) {
        while (*s == ' ' || *s == '\t' || *s == '\r' || *s == '\n') s++;
        if (*s == '#') { while (*s && *s != '\n') s++; continue; }
        if (!*s) break;
        return !strncmp(s, "Num_Devices", 11) || !strncmp(s, "Polling_Period", 14) ||
               !strncmp(s, "Timeout", 7) || (!strncmp(s, "device", 6) && isdigit((unsigned char)s[6]));
    }
    return 0;
}

static int parse_mbconfig(parser_t *p, char *text)
{
    struct plcrt_master *m = p->m;
    long num_devices = -1;
    int num_line = 0, poll_line = 0, timeout_line = 0;
    uint64_t poll_ns = 100000000ull, timeout_ns = 1000000000ull;
    static mb_dev_t devs[MAX_DEVICES];
    memset(devs, 0, sizeof devs);
    int lineno = 0;
    char *cur = text;
    while (cur) {
        char *nl = strchr(cur, '\n');
        if (nl) *nl = 0;
        char *line = cur;
        cur = nl ? nl + 1 : NULL;
        lineno++;
        char *s = trim(line);
        if (!*s || *s == '#') continue;
        char *eq = strchr(s, '=');
        if (!eq) return perr(p, lineno, "expected 'key = \"value\"'");
        *eq = 0;
        char *key = trim(s), *val = trim(eq + 1);
        size_t vl = strlen(val);
        if (vl >= 2 && val[0] == '"' && val[vl - 1] == '"') { val[vl - 1] = 0; val++; }
        long x;
        if (!strcmp(key, "Num_Devices")) {
            if (parse_int(p, lineno, key, val, 0, MAX_DEVICES, &num_devices)) return -1;
            num_line = lineno;
        } else if (!strcmp(key, "Polling_Period")) {
            if (parse_int(p, lineno, key, val, 1, 3600000, &x)) return -1;
            poll_ns = (uint64_t)x * 1000000ull;
            poll_line = lineno;
        } else if (!strcmp(key, "Timeout")) {
            if (parse_int(p, lineno, key, val, 1, 3600000, &x)) return -1;
            timeout_ns = (uint64_t)x * 1000000ull;
            timeout_line = lineno;
        } else if (!strncmp(key, "device", 6) && isdigit((unsigned char)key[6])) {
            char *dot;
            long idx = strtol(key + 6, &dot, 10);
            if (*dot != '.') return perr(p, lineno, "unknown key '%s'", key);
            if (idx < 0 || idx >= MAX_DEVICES) return perr(p, lineno, "%s: device index out of range", key);
            if (num_devices >= 0 && idx >= num_devices)
                return perr(p, lineno, "%s: device%ld but Num_Devices = %ld (line %d)", key, idx, num_devices, num_line);
            mb_dev_t *d = &devs[idx];
            if (!d->seen) { d->seen = 1; d->line = lineno; }
            const char *k = dot + 1;
            if (!strcmp(k, "name")) {
                if (set_str(p, lineno, key, d->name, sizeof d->name, val)) return -1;
            } else if (!strcmp(k, "slave_id")) {
                if (parse_int(p, lineno, key, val, 0, 255, &d->slave_id)) return -1;
            } else if (!strcmp(k, "protocol")) {
                if (set_str(p, lineno, key, d->protocol, sizeof d->protocol, val)) return -1;
                if (strcmp(val, "TCP") && strcmp(val, "RTU") && strcmp(val, "ESP32") && strcmp(val, "ESP8266"))
                    return perr(p, lineno, "%s: unknown protocol '%s'", key, val);
            } else if (!strcmp(k, "address")) {
                if (set_str(p, lineno, key, d->address, sizeof d->address, val)) return -1;
            } else if (!strcmp(k, "IP_Port")) {
                if (parse_int(p, lineno, key, val, 1, 65535, &d->port)) return -1;
            } else if (!strncmp(k, "RTU_", 4) && (!strcmp(k + 4, "Baud_Rate") || !strcmp(k + 4, "Parity") ||
                                                  !strcmp(k + 4, "Data_Bits") || !strcmp(k + 4, "Stop_Bits") ||
                                                  !strcmp(k + 4, "TX_Pause"))) {
                /* serial settings: checked at the end, for RTU devices only (OpenPLC writes
                 * "None" into them for TCP devices) */
                int f = !strcmp(k + 4, "Baud_Rate") ? 0 : !strcmp(k + 4, "Parity") ? 1
                      : !strcmp(k + 4, "Data_Bits") ? 2 : !strcmp(k + 4, "Stop_Bits") ? 3 : 4;
                if (set_str(p, lineno, key, d->rtu_val[f], sizeof d->rtu_val[f], val)) return -1;
                d->rtu_line[f] = lineno;
            } else {
                int found = 0;
                for (int b = 0; b < 5 && !found; b++) {
                    size_t bl = strlen(mb_block[b]);
                    if (!strncmp(k, mb_block[b], bl) && (!strcmp(k + bl, "_Start") || !strcmp(k + bl, "_Size"))) {
                        int is_size = !strcmp(k + bl, "_Size");
                        if (parse_int(p, lineno, key, val, 0, 65535, &x)) return -1;
                        if (is_size) d->size[b] = x; else d->start[b] = x;
                        d->has[b * 2 + is_size] = lineno;
                        found = 1;
                    }
                }
                if (!found) return perr(p, lineno, "unknown key '%s'", key);
            }
        } else {
            return perr(p, lineno, "unknown key '%s' (mbconfig.cfg: Num_Devices, Polling_Period, Timeout, deviceN.*)", key);
        }
    }
    (void)poll_line;
    (void)timeout_line;
    if (num_devices < 0) return perr(p, 1, "Num_Devices missing");
    int ix = 100 * 8, qx = 100 * 8, iw = 100, qw = 100; /* OpenPLC maps from %IX100.0 / %IW100 on */
    for (int i = 0; i < num_devices; i++) {
        mb_dev_t *d = &devs[i];
        if (!d->seen) return perr(p, num_line, "Num_Devices = %ld but device%d is not configured", num_devices, i);
        if (!d->name[0]) snprintf(d->name, sizeof d->name, "device%d", i);
        if (find_device(m, d->name) >= 0) snprintf(d->name, sizeof d->name, "device%d", i);
        int rtu = !strcmp(d->protocol, "RTU");
        if (!rtu && strcmp(d->protocol, "TCP") && strcmp(d->protocol, "ESP32") && strcmp(d->protocol, "ESP8266"))
            return perr(p, d->line, "device%d: protocol '%s' is not supported (TCP, RTU, ESP32, ESP8266)", i,
                        d->protocol[0] ? d->protocol : "(missing)");
        if (!d->address[0]) return perr(p, d->line, "device%d.address missing", i);
        plcrt_device_t *dev = &m->devices[m->n_devices++];
        memset(dev, 0, sizeof *dev);
        snprintf(dev->name, sizeof dev->name, "%s", d->name);
        snprintf(dev->host, sizeof dev->host, "%s", d->address);
        dev->line = d->line;
        dev->port = d->port ? (int)d->port : 502;
        dev->unit_id = (int)d->slave_id;
        dev->timeout_ns = timeout_ns;
        dev->poll_ns = poll_ns;
        dev->errors_word = dev->online_bit = dev->ext_fd = dev->unit_word = -1;
        dev->rtu = rtu;
        dev->baud = 115200; /* OpenPLC's default rate */
        dev->parity = 'N';
        dev->data_bits = 8;
        dev->stop_bits = 1;
        if (rtu) {
            static const char *const rk[5] = {"RTU_Baud_Rate", "RTU_Parity", "RTU_Data_Bits", "RTU_Stop_Bits", "RTU_TX_Pause"};
            char key[64];
            long x;
            for (int f = 0; f < 5; f++) {
                if (!d->rtu_line[f]) continue;
                snprintf(key, sizeof key, "device%d.%s", i, rk[f]);
                const char *v = d->rtu_val[f];
                int ln = d->rtu_line[f];
                if (f == 1) {
                    if (!(dev->parity = parity_of(v))) return perr(p, ln, "%s: '%s' is not None, Even or Odd", key, v);
                    continue;
                }
                static const long lo[5] = {1, 0, 7, 1, 0}, hi[5] = {4000000, 0, 8, 2, 3600000};
                if (parse_int(p, ln, key, v, lo[f], hi[f], &x)) return -1;
                if (f == 0 && !valid_baud(x)) return perr(p, ln, "%s: %ld is not a standard rate (300 .. 921600)", key, x);
                if (f == 2 && x != 8) return perr(p, ln, "%s: %ld: " RTU_8_BITS, key, x);
                if (f == 0) dev->baud = (int)x;
                else if (f == 2) dev->data_bits = (int)x;
                else if (f == 3) dev->stop_bits = (int)x;
                else dev->pause_ns = (uint64_t)x * 1000000ull;
            }
        }
        if (rtu && dev->unit_id > 247)
            return perr(p, d->line, "device%d.slave_id: %d is not a Modbus RTU address (0..247)", i, dev->unit_id);
        assign_bus(m, dev);
        if (check_bus(p, dev)) return -1;
        /* OpenPLC's order per device: DI, coils, IR, HR read, HR write */
        static const char tables[5] = {'d', 'c', 'i', 'h', 'h'};
        static const int writes[5] = {0, 1, 0, 0, 1};
        for (int b = 0; b < 5; b++) {
            if (d->size[b] == 0) continue;
            int line = d->has[b * 2 + 1];
            plcrt_range_t *r = &m->ranges[m->n_ranges];
            memset(r, 0, sizeof *r);
            snprintf(r->name, sizeof r->name, "device%d.%s", i, mb_block[b]);
            r->line = line;
            r->is_write = writes[b];
            r->table = tables[b];
            r->start = (int)d->start[b];
            r->size = (int)d->size[b];
            r->policy = POLICY_CYCLE;
            r->trigger = r->done = r->error = r->status = r->length = -1;
            r->dev = m->n_devices - 1;
            r->out_unit = r->is_write ? -1 : dev->unit_id; /* a write: not before the first exchange */
            int limit = range_limit(r);
            if (r->size > limit)
                return perr(p, line, "%s_Size: %d in one request (at most %d)", mb_block[b], r->size, limit);
            if (r->start + r->size > 65536)
                return perr(p, line, "%s: start + size runs past Modbus address 65535", mb_block[b]);
            int bits = r->table == 'c' || r->table == 'd';
            int *next = bits ? (r->is_write ? &qx : &ix) : (r->is_write ? &qw : &iw);
            r->image = *next;
            if (claim(p, line, r->is_write ? 'Q' : 'I', bits ? 'X' : 'W', r->image, r->size, mb_block[b]))
                return -1;
            *next += r->size;
            m->n_ranges++;
        }
    }
    return 0;
}

int plcrt_master_parse(plcrt_t *rt, const char *name, const char *text, struct plcrt_master **out)
{
    parser_t *p = calloc(1, sizeof *p);
    struct plcrt_master *m = calloc(1, sizeof *m);
    char *copy = strdup(text);
    int rc = -1;
    if (!p || !m || !copy) {
        plcrt_seterr(rt, "%s: error: out of memory", name);
        goto out;
    }
    m->devices = calloc(MAX_DEVICES, sizeof *m->devices);
    m->ranges = calloc(MAX_RANGES, sizeof *m->ranges);
    if (!m->devices || !m->ranges) {
        plcrt_seterr(rt, "%s: error: out of memory", name);
        goto out;
    }
    m->reconnect_min_ns = 100000000ull;
    m->reconnect_max_ns = 5000000000ull;
    m->slave_port = -1;
    m->retain_request = m->retain_saved = -1;
    m->slave_watch = m->slave_watch_count = -1;
    p->rt = rt;
    p->file = name;
    p->m = m;
    rc = plcrt_config_is_mbconfig(text) ? parse_mbconfig(p, copy) : parse_plcrt(p, copy);
    if (rc == 0 && m->reconnect_max_ns < m->reconnect_min_ns) {
        plcrt_seterr(rt, "%s: error: reconnect_max is shorter than reconnect_min", name);
        rc = -1;
    }
out:
    free(copy);
    free(p);
    if (rc == 0) {
        pthread_mutex_init(&m->lock, NULL);
        pthread_condattr_t ca;
        pthread_condattr_init(&ca);
        pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
        pthread_cond_init(&m->wake, &ca);
        pthread_condattr_destroy(&ca);
        m->rt = rt;
        *out = m;
    } else if (m) {
        free(m->devices);
        free(m->ranges);
        free(m);
    }
    return rc;
}
