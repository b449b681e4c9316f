/* mipemu core: register maps, MIP semantics, radio model, trace. No clocks, no sockets. */
#include "mipemu.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define AREA MIPEMU_AREA_REGS

/* ---- PRNG: xoshiro256** seeded by splitmix64, so results are the same on every machine ---- */

typedef struct { uint64_t s[4]; } rng_t;

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static void rng_seed(rng_t *r, uint64_t seed)
{
    for (int i = 0; i < 4; i++)
        r->s[i] = splitmix64(&seed);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

static uint64_t rng_next(rng_t *r)
{
    uint64_t *s = r->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

/* uniform in [0, 1) with 53 bits */
static double rng_unit(rng_t *r) { return (double)(rng_next(r) >> 11) * (1.0 / 9007199254740992.0); }

/* uniform integer in [lo, hi] (the range is tiny, modulo bias is irrelevant here) */
static int rng_range(rng_t *r, int lo, int hi) { return lo + (int)(rng_next(r) % (uint64_t)(hi - lo + 1)); }

/* ---- state ---- */

/* One end of one direction pair: the buffers a Modbus client sees at one device for one station. */
typedef struct side {
    uint16_t wr[AREA];       /* write data */
    uint16_t wr_count;       /* "number of write registers" */
    uint16_t rstat;          /* read status */
    uint16_t rd_count;       /* number of registers received */
    uint16_t rd[AREA];       /* read data */
    uint16_t queued[AREA];   /* static mode: content last queued, for change detection */
    uint32_t gen;            /* generation of the queued block; bumped by every new block */
    int pending;             /* a block is queued and not yet confirmed (read-status bit 4) */
    uint32_t delivered_gen;  /* receiver side bookkeeping: generation last delivered from the peer */
    int delivered_any;
} side_t;

typedef struct channel { int bad; } channel_t; /* Gilbert-Elliott state of one direction */

typedef struct station {
    side_t mdp;              /* MDP-810 buffers for this station */
    side_t trm;              /* TRM-810 buffers */
    int base_down_dbm, base_up_dbm; /* -dBm levels around which the noise plays */
    uint8_t fs_down, fs_up;  /* last measured -dBm: station hears MDP / MDP hears station (0: none yet) */
    uint16_t status;         /* MDP register 1 */
    int fails;               /* unanswered polls in a row */
    int record_lost;         /* the scripted lose_record fault has struck this station */
    channel_t ch_down, ch_up;
    mipemu_stats st;
} station_t;

enum phase { PH_DOWN, PH_UP, PH_ACK, PH_WAIT };

typedef struct slot {
    int station;             /* index 0..n-1 */
    enum phase phase;
    uint64_t t_slot;         /* slot start */
    uint64_t t_start;        /* start of the telegram in flight */
    uint64_t t_end;          /* end of the telegram in flight, or of the wait */
    int down_len;            /* registers in the downlink block of this slot, -1 none */
    uint32_t down_gen;
    int up_len;              /* registers in the uplink block of this slot, -1 none */
    uint32_t up_gen;
    int down_ok, up_ok;
    int down_fate, up_fate;  /* scripted fates (MIPEMU_FATE_*) of this slot's blocks that arrived */
    uint8_t fs_down;         /* what the station measured on this poll; reported in its answer */
    uint16_t blk[AREA];      /* the block in flight (copied when the telegram starts) */
} slot_t;

struct mipemu_net {
    mipemu_config cfg;
    uint64_t now;
    rng_t rng;
    double g2b_down, b2g_down, g2b_up, b2g_up;
    station_t *st;
    slot_t slot;
    uint64_t seq;            /* trace line number */
    mipemu_trace_fn trace;
    void *trace_user;
    mipemu_fate_fn fate;
    void *fate_user;
};

/* ---- config ---- */

void mipemu_config_default(mipemu_config *c)
{
    memset(c, 0, sizeof *c);
    c->stations = 1;
    c->mode = MIPEMU_DYNAMIC;
    c->static_registers = AREA;
    c->loss_down = 0.0;
    c->loss_up = 0.0;
    c->burst = 0.0;
    c->seed = 1;
    c->bitrate = 9600;
    c->slot_gap_ns = 20000000ULL; /* 20 ms */
    c->overhead_bytes = 12;
    c->fail_polls = 3;
    c->allow_127 = 0;
    c->lose_record = 0;
}

static int config_check(const mipemu_config *c, char *err, size_t n)
{
#define BAD(...) do { if (err && n) snprintf(err, n, __VA_ARGS__); return -1; } while (0)
    if (c->stations < 1 || c->stations > MIPEMU_MAX_STATIONS) BAD("stations must be 1..%d", MIPEMU_MAX_STATIONS);
    if (c->mode != MIPEMU_DYNAMIC && c->mode != MIPEMU_STATIC) BAD("mode must be static or dynamic");
    if (c->static_registers < 1 || c->static_registers > AREA) BAD("static registers must be 1..%d", AREA);
    if (!(c->loss_down >= 0.0 && c->loss_down <= 1.0)) BAD("downlink loss must be 0..1");
    if (!(c->loss_up >= 0.0 && c->loss_up <= 1.0)) BAD("uplink loss must be 0..1");
    if (!(c->burst == 0.0 || (c->burst >= 1.0 && c->burst <= 1e6))) BAD("burst length must be 0 (off) or 1..1000000");
    if (c->bitrate < 300 || c->bitrate > 10000000) BAD("bit rate must be 300..10000000");
    if (c->slot_gap_ns > 60000000000ULL) BAD("slot gap must be at most 60 s");
    if (c->overhead_bytes < 1 || c->overhead_bytes > 255) BAD("overhead bytes must be 1..255");
    if (c->fail_polls < 1 || c->fail_polls > 255) BAD("fail polls must be 1..255");
    if (c->lose_record < 0 || c->lose_record > 65535) BAD("lose record must be 0 (off) or 1..65535");
    return 0;
#undef BAD
}

/* Gilbert-Elliott with a lossless good state and a lossy bad state: the stationary share of the
 * bad state is the configured loss p, the mean stay in it is L telegrams. g2b may exceed 1 for
 * p > L/(L+1); it is clamped, which lowers the effective loss (documented). */
static void ge_params(double p, double L, double *g2b, double *b2g)
{
    *b2g = 1.0 / L;
    if (p >= 1.0) { *g2b = 1.0; *b2g = 0.0; return; }
    double g = p / (L * (1.0 - p));
    *g2b = g > 1.0 ? 1.0 : g;
}

uint64_t mipemu_telegram_ns(const mipemu_config *c, int nregs)
{
    uint64_t bytes = (uint64_t)c->overhead_bytes + 2u * (uint64_t)(nregs > 0 ? nregs : 0);
    return bytes * 8u * 1000000000ULL / c->bitrate;
}

/* ---- trace ---- */

static void emit(mipemu_net *net, uint64_t t, const char *fmt, ...)
{
    if (!net->trace)
        return;
    char line[512];
    int n = snprintf(line, sizeof line, "{\"t\":%" PRIu64 ",\"seq\":%" PRIu64 ",", t, net->seq++);
    va_list ap;
    va_start(ap, fmt);
    n += vsnprintf(line + n, sizeof line - (size_t)n - 2, fmt, ap);
    va_end(ap);
    if (n > (int)sizeof line - 3)
        n = (int)sizeof line - 3;
    line[n++] = '}';
    line[n++] = '\n';
    line[n] = 0;
    net->trace(net->trace_user, line, (size_t)n);
}

void mipemu_net_set_trace(mipemu_net *net, mipemu_trace_fn fn, void *user)
{
    net->trace = fn;
    net->trace_user = user;
}

void mipemu_net_trace_note(mipemu_net *net, const char *fields)
{
    if (net && fields)
        emit(net, net->now, "%s", fields);
}

void mipemu_net_set_fate(mipemu_net *net, mipemu_fate_fn fn, void *user)
{
    net->fate = fn;
    net->fate_user = user;
}

/* ---- network ---- */

static void slot_begin(mipemu_net *net, int station, uint64_t t);

mipemu_net *mipemu_net_new(const mipemu_config *c, char *err, size_t errn)
{
    if (config_check(c, err, errn) != 0)
        return NULL;
    mipemu_net *net = calloc(1, sizeof *net);
    if (!net)
        return NULL;
    net->cfg = *c;
    net->st = calloc((size_t)c->stations, sizeof *net->st);
    if (!net->st) {
        free(net);
        if (err && errn) snprintf(err, errn, "out of memory");
        return NULL;
    }
    rng_seed(&net->rng, c->seed);
    if (c->burst >= 1.0) {
        ge_params(c->loss_down, c->burst, &net->g2b_down, &net->b2g_down);
        ge_params(c->loss_up, c->burst, &net->g2b_up, &net->b2g_up);
    }
    for (int i = 0; i < c->stations; i++) {
        station_t *s = &net->st[i];
        s->base_down_dbm = rng_range(&net->rng, 55, 100);
        s->base_up_dbm = s->base_down_dbm + rng_range(&net->rng, -4, 4);
        if (c->mode == MIPEMU_STATIC) {
            s->mdp.wr_count = (uint16_t)c->static_registers;
            s->trm.wr_count = (uint16_t)c->static_registers;
        }
    }
    slot_begin(net, 0, 0);
    return net;
}

void mipemu_net_free(mipemu_net *net)
{
    if (!net)
        return;
    free(net->st);
    free(net);
}

uint64_t mipemu_net_now(const mipemu_net *net) { return net->now; }
uint64_t mipemu_net_next_event(const mipemu_net *net) { return net->slot.t_end; }
int mipemu_net_stations(const mipemu_net *net) { return net->cfg.stations; }

int mipemu_net_stats(const mipemu_net *net, int station, mipemu_stats *out)
{
    if (station < 1 || station > net->cfg.stations)
        return -1;
    *out = net->st[station - 1].st;
    return 0;
}

/* ---- radio ---- */

/* Decides whether one telegram in one direction is lost. */
static int lose(mipemu_net *net, channel_t *ch, double p, double g2b, double b2g)
{
    if (net->cfg.burst >= 1.0) {
        /* advance the channel state, then the telegram is lost iff the channel is bad */
        double u = rng_unit(&net->rng);
        if (ch->bad) {
            if (u < b2g) ch->bad = 0;
        } else {
            if (u < g2b) ch->bad = 1;
        }
        return ch->bad;
    }
    if (p <= 0.0)
        return 0;
    return rng_unit(&net->rng) < p;
}

static uint8_t measure(mipemu_net *net, int base)
{
    int v = base + rng_range(&net->rng, -3, 3);
    if (v < 1) v = 1;
    if (v > 255) v = 255;
    return (uint8_t)v;
}

/* The scripted fate of a telegram carrying a block: the hook's verdict (also into *verdict, for
 * the trace), and lose_record (the first uplink block with register 0 = lose_record is lost, once
 * per station, whatever the hook says). */
static int scripted_fate(mipemu_net *net, station_t *s, int up, const uint16_t *blk, int len, int *verdict)
{
    int f = MIPEMU_FATE_OK;
    if (net->fate) {
        f = net->fate(net->fate_user, net->slot.station + 1, up, blk, len);
        if (f < MIPEMU_FATE_OK || f > MIPEMU_FATE_DROP)
            f = MIPEMU_FATE_OK;
    }
    *verdict = f;
    if (up && net->cfg.lose_record && !s->record_lost && len > 0 && blk[0] == (uint16_t)net->cfg.lose_record) {
        s->record_lost = 1; /* on top of (and without disturbing) the random losses */
        f = MIPEMU_FATE_LOST;
    }
    return f;
}

static const char *fate_field(int f)
{
    switch (f) {
    case MIPEMU_FATE_LOST: return ",\"fate\":\"lost\"";
    case MIPEMU_FATE_DUP: return ",\"fate\":\"dup\"";
    case MIPEMU_FATE_DROP: return ",\"fate\":\"drop\"";
    default: return "";
    }
}

/* The block a side would send now, or -1: dynamic = the last written block until confirmed,
 * static = the N mirrored registers while a change is unconfirmed. */
static int pending_len(const mipemu_net *net, const side_t *sd)
{
    if (!sd->pending)
        return -1;
    return net->cfg.mode == MIPEMU_STATIC ? net->cfg.static_registers : sd->wr_count;
}

static void deliver(side_t *rx, const uint16_t *blk, int len, uint32_t gen, uint64_t *blocks, uint64_t *dups)
{
    memcpy(rx->rd, blk, (size_t)len * sizeof *blk);
    rx->rd_count = (uint16_t)len;
    rx->rstat |= MIPEMU_RS_NEW_DATA;
    (*blocks)++;
    if (rx->delivered_any && rx->delivered_gen == gen)
        (*dups)++;
    rx->delivered_any = 1;
    rx->delivered_gen = gen;
}

static void confirm(mipemu_net *net, side_t *tx, uint32_t gen, uint64_t *count)
{
    (*count)++;
    if (tx->gen != gen)
        return; /* a newer block replaced it meanwhile: that one still waits */
    tx->pending = 0;
    tx->rstat &= (uint16_t)~(MIPEMU_RS_WRITE_WAITING | MIPEMU_RS_WRITE_UNCONFIRMED);
    if (net->cfg.mode == MIPEMU_DYNAMIC)
        tx->wr_count = 0;
}

static void slot_begin(mipemu_net *net, int station, uint64_t t)
{
    slot_t *sl = &net->slot;
    station_t *s = &net->st[station];
    sl->station = station;
    sl->t_slot = t;
    sl->phase = PH_DOWN;
    sl->down_len = pending_len(net, &s->mdp);
    sl->down_gen = s->mdp.gen;
    sl->up_len = -1;
    sl->down_ok = sl->up_ok = 0;
    sl->down_fate = sl->up_fate = MIPEMU_FATE_OK;
    if (sl->down_len >= 0)
        memcpy(sl->blk, s->mdp.wr, (size_t)sl->down_len * sizeof(uint16_t));
    if (sl->down_len >= 0 && s->mdp.rstat & MIPEMU_RS_WRITE_WAITING)
        s->status &= (uint16_t)~MIPEMU_ST_DOWN_RESEND;
    else if (sl->down_len >= 0)
        s->status |= MIPEMU_ST_DOWN_RESEND;
    s->st.polls++;
    sl->t_start = t;
    sl->t_end = t + mipemu_telegram_ns(&net->cfg, sl->down_len);
}

static void trace_telegram(mipemu_net *net, const char *kind, const char *dir, int len, int lost,
                           const char *extra)
{
    slot_t *sl = &net->slot;
    int regs = len < 0 ? 0 : len;
    uint64_t bytes = (uint64_t)net->cfg.overhead_bytes + 2u * (uint64_t)regs;
    if (len >= 0)
        emit(net, sl->t_end, "\"ev\":\"radio\",\"kind\":\"%s\",\"dir\":\"%s\",\"st\":%d,\"t0\":%" PRIu64
             ",\"bytes\":%" PRIu64 ",\"regs\":%d,\"r0\":%u,\"lost\":%s%s",
             kind, dir, sl->station + 1, sl->t_start, bytes, regs, (unsigned)(len > 0 ? sl->blk[0] : 0),
             lost ? "true" : "false", extra);
    else
        emit(net, sl->t_end, "\"ev\":\"radio\",\"kind\":\"%s\",\"dir\":\"%s\",\"st\":%d,\"t0\":%" PRIu64
             ",\"bytes\":%" PRIu64 ",\"regs\":0,\"lost\":%s%s",
             kind, dir, sl->station + 1, sl->t_start, bytes, lost ? "true" : "false", extra);
}

static void poll_failed(mipemu_net *net, station_t *s)
{
    s->status &= (uint16_t)~MIPEMU_ST_ANSWERED;
    if (s->fails < 65535)
        s->fails++;
    if (s->fails >= net->cfg.fail_polls && !(s->status & MIPEMU_ST_UNREACHABLE)) {
        s->status |= MIPEMU_ST_UNREACHABLE;
        emit(net, net->slot.t_end, "\"ev\":\"station\",\"st\":%d,\"state\":\"unreachable\",\"fails\":%d",
             net->slot.station + 1, s->fails);
    }
}

/* Processes the event at slot.t_end and schedules the next one. */
static void step(mipemu_net *net)
{
    slot_t *sl = &net->slot;
    station_t *s = &net->st[sl->station];
    const mipemu_config *c = &net->cfg;
    uint64_t gap = c->slot_gap_ns;

    switch (sl->phase) {
    case PH_DOWN: {
        int lost = lose(net, &s->ch_down, c->loss_down, net->g2b_down, net->b2g_down);
        int verdict = MIPEMU_FATE_OK;
        int fate = sl->down_len >= 0 ? scripted_fate(net, s, 0, sl->blk, sl->down_len, &verdict) : MIPEMU_FATE_OK;
        if (fate == MIPEMU_FATE_LOST)
            lost = 1;
        sl->down_fate = lost ? MIPEMU_FATE_OK : fate;
        s->st.tel_down++;
        if (lost)
            s->st.lost_down++;
        /* the MDP has sent the block whether or not it arrives: bit 1 clears */
        if (sl->down_len >= 0 && s->mdp.gen == sl->down_gen)
            s->mdp.rstat &= (uint16_t)~MIPEMU_RS_WRITE_WAITING;
        trace_telegram(net, "poll", "down", sl->down_len, lost, fate_field(verdict));
        if (lost) {
            /* no answer: the MDP waits as long as an empty answer would take */
            sl->phase = PH_WAIT;
            sl->t_start = sl->t_end;
            sl->t_end = sl->t_end + gap + mipemu_telegram_ns(c, 0) + gap;
            poll_failed(net, s);
            return;
        }
        sl->down_ok = 1;
        sl->fs_down = measure(net, s->base_down_dbm);
        if (sl->down_len >= 0 && fate != MIPEMU_FATE_DROP)
            deliver(&s->trm, sl->blk, sl->down_len, sl->down_gen, &s->st.blocks_down, &s->st.dup_down);
        /* the station answers with its pending block, if any */
        sl->up_len = pending_len(net, &s->trm);
        sl->up_gen = s->trm.gen;
        if (sl->up_len >= 0)
            memcpy(sl->blk, s->trm.wr, (size_t)sl->up_len * sizeof(uint16_t));
        sl->phase = PH_UP;
        sl->t_start = sl->t_end + gap;
        sl->t_end = sl->t_start + mipemu_telegram_ns(c, sl->up_len);
        return;
    }
    case PH_UP: {
        int lost = lose(net, &s->ch_up, c->loss_up, net->g2b_up, net->b2g_up);
        int verdict = MIPEMU_FATE_OK;
        int fate = sl->up_len >= 0 ? scripted_fate(net, s, 1, sl->blk, sl->up_len, &verdict) : MIPEMU_FATE_OK;
        if (fate == MIPEMU_FATE_LOST)
            lost = 1;
        sl->up_fate = lost ? MIPEMU_FATE_OK : fate;
        s->st.tel_up++;
        if (lost)
            s->st.lost_up++;
        if (sl->up_len >= 0 && s->trm.gen == sl->up_gen)
            s->trm.rstat &= (uint16_t)~MIPEMU_RS_WRITE_WAITING;
        {
            char extra[48];
            snprintf(extra, sizeof extra, "%s%s", sl->down_len >= 0 ? ",\"ack\":true" : "",
                     fate_field(verdict));
            trace_telegram(net, "answer", "up", sl->up_len, lost, extra);
        }
        if (lost) {
            poll_failed(net, s);
            sl->phase = PH_WAIT;
            sl->t_start = sl->t_end;
            sl->t_end = sl->t_end + gap;
            return;
        }
        sl->up_ok = 1;
        s->fails = 0;
        if (s->status & MIPEMU_ST_UNREACHABLE)
            emit(net, sl->t_end, "\"ev\":\"station\",\"st\":%d,\"state\":\"reachable\"", sl->station + 1);
        s->status |= MIPEMU_ST_ANSWERED | MIPEMU_ST_EVER_ANSWERED;
        s->status &= (uint16_t)~MIPEMU_ST_UNREACHABLE;
        s->fs_up = measure(net, s->base_up_dbm);
        s->fs_down = sl->fs_down;
        if (sl->down_len >= 0 && sl->down_fate != MIPEMU_FATE_DUP) {
            confirm(net, &s->mdp, sl->down_gen, &s->st.confirmed_down);
            s->status &= (uint16_t)~MIPEMU_ST_DOWN_RESEND;
        }
        if (sl->up_len >= 0) {
            if (sl->up_fate != MIPEMU_FATE_DROP)
                deliver(&s->mdp, sl->blk, sl->up_len, sl->up_gen, &s->st.blocks_up, &s->st.dup_up);
            sl->phase = PH_ACK;
            sl->t_start = sl->t_end + gap;
            sl->t_end = sl->t_start + mipemu_telegram_ns(c, -1);
            return;
        }
        sl->phase = PH_WAIT;
        sl->t_start = sl->t_end;
        sl->t_end = sl->t_end + gap;
        return;
    }
    case PH_ACK: {
        int lost = lose(net, &s->ch_down, c->loss_down, net->g2b_down, net->b2g_down);
        if (sl->up_fate == MIPEMU_FATE_DUP)
            lost = 1; /* the uplink block's confirmation is lost */
        s->st.tel_down++;
        if (lost)
            s->st.lost_down++;
        trace_telegram(net, "ack", "down", -1, lost, fate_field(sl->up_fate == MIPEMU_FATE_DUP ? MIPEMU_FATE_DUP : MIPEMU_FATE_OK));
        if (!lost)
            confirm(net, &s->trm, sl->up_gen, &s->st.confirmed_up);
        sl->phase = PH_WAIT;
        sl->t_start = sl->t_end;
        sl->t_end = sl->t_end + gap;
        return;
    }
    case PH_WAIT:
        slot_begin(net, (sl->station + 1) % c->stations, sl->t_end);
        return;
    }
}

int mipemu_net_advance(mipemu_net *net, uint64_t now_ns)
{
    if (now_ns < net->now)
        return -1;
    while (net->slot.t_end <= now_ns)
        step(net);
    net->now = now_ns;
    return 0;
}

/* ---- Modbus ---- */

long mipemu_frame_length(const uint8_t *b, size_t len)
{
    if (len < 7)
        return 0;
    unsigned proto = (unsigned)b[2] << 8 | b[3];
    unsigned mlen = (unsigned)b[4] << 8 | b[5];
    if (proto != 0 || mlen < 2 || mlen > MIPEMU_MBAP_LEN_MAX)
        return -1;
    return (long)mlen + 6;
}

/* what an address is at an endpoint */
enum reg_kind {
    R_NONE, R_FIELD, R_STATUS, R_RSTAT, R_RCOUNT, R_WCOUNT, R_WDATA, R_RDATA
};

typedef struct map {
    int is_mdp;
    unsigned wcount, wbase, rstat, rcount, rbase; /* addresses */
} map_t;

static const map_t MDP_MAP = { 1, 9, 10, 198, 199, 200 };
static const map_t TRM_MAP = { 0, 2000, 2001, 2198, 2199, 2200 };

static enum reg_kind kind_of(const map_t *m, unsigned a)
{
    if (m->is_mdp) {
        switch (a) {
        case 0: return R_FIELD;
        case 1: return R_STATUS;
        case 2: return R_RSTAT;
        case 4: return R_RCOUNT;
        default: break;
        }
    }
    if (a == m->wcount) return R_WCOUNT;
    if (a >= m->wbase && a < m->wbase + AREA) return R_WDATA;
    if (a == m->rstat) return R_RSTAT;
    if (a == m->rcount) return R_RCOUNT;
    if (a >= m->rbase && a < m->rbase + AREA) return R_RDATA;
    return R_NONE;
}

static uint16_t get_reg(const map_t *m, const station_t *s, const side_t *sd, unsigned a)
{
    switch (kind_of(m, a)) {
    case R_FIELD: return (uint16_t)((unsigned)s->fs_down << 8 | s->fs_up);
    case R_STATUS: return s->status;
    case R_RSTAT: return sd->rstat;
    case R_RCOUNT: return sd->rd_count;
    case R_WCOUNT: return sd->wr_count;
    case R_WDATA: return sd->wr[a - m->wbase];
    case R_RDATA: return sd->rd[a - m->rbase];
    default: return 0;
    }
}

/* The read every client makes (note, section 1): status, count and data in one request from the
 * read-status register on. Contiguous in both maps, so it needs no per-register lookup. */
static int is_status_read(const map_t *m, unsigned a, unsigned q)
{
    return a == m->rstat && m->rcount == a + 1 && m->rbase == a + 2 && q <= AREA + 2;
}

static int range_readable(const map_t *m, unsigned a, unsigned q)
{
    if (is_status_read(m, a, q))
        return 1;
    for (unsigned i = 0; i < q; i++)
        if (kind_of(m, a + i) == R_NONE)
            return 0;
    return 1;
}

static int range_writable(const map_t *m, unsigned a, unsigned q)
{
    for (unsigned i = 0; i < q; i++)
        if (kind_of(m, a + i) != R_WDATA)
            return 0;
    return 1;
}

static int touches_read_area(const map_t *m, unsigned a, unsigned q)
{
    return a < m->rbase + AREA && a + q > m->rbase;
}

static unsigned get16(const uint8_t *p) { return (unsigned)p[0] << 8 | p[1]; }
static void put16(uint8_t *p, unsigned v) { p[0] = (uint8_t)(v >> 8); p[1] = (uint8_t)v; }

/* Applies a write into the write area (addresses checked). Static mode: change detection. */
static void apply_write(mipemu_net *net, const map_t *m, side_t *sd, unsigned a, unsigned q,
                        const uint8_t *vals)
{
    for (unsigned i = 0; i < q; i++)
        sd->wr[a - m->wbase + i] = (uint16_t)get16(vals + 2 * i);
    if (net->cfg.mode == MIPEMU_DYNAMIC) {
        /* a new block: replaces whatever was queued, sent or not */
        sd->wr_count = (uint16_t)q;
        sd->gen++;
        sd->pending = 1;
        sd->rstat |= MIPEMU_RS_WRITE_WAITING | MIPEMU_RS_WRITE_UNCONFIRMED;
    } else {
        size_t n = (size_t)net->cfg.static_registers;
        if (memcmp(sd->wr, sd->queued, n * sizeof(uint16_t)) != 0) {
            memcpy(sd->queued, sd->wr, n * sizeof(uint16_t));
            sd->gen++;
            sd->pending = 1;
            sd->rstat |= MIPEMU_RS_WRITE_WAITING | MIPEMU_RS_WRITE_UNCONFIRMED;
        }
    }
}

static long exception_reply(uint8_t *out, const uint8_t *req, unsigned fc, unsigned code)
{
    memcpy(out, req, 7);
    put16(out + 4, 3);
    out[7] = (uint8_t)(fc | 0x80);
    out[8] = (uint8_t)code;
    return 9;
}

long mipemu_handle(mipemu_net *net, int ep, const uint8_t *req, size_t len, uint8_t *out, size_t out_cap)
{
    if (!net || !req || !out || out_cap < MIPEMU_RESPONSE_MAX || ep < 0 || ep > net->cfg.stations)
        return -1;
    if (len < 8 || mipemu_frame_length(req, len) != (long)len) {
        /* traced too, so a dropped connection shows in the sequence diagram */
        unsigned u = len >= 7 ? req[6] : 0;
        emit(net, net->now, "\"ev\":\"modbus\",\"ep\":\"%s\",\"st\":%u,\"close\":\"malformed frame\",\"len\":%zu",
             ep == MIPEMU_EP_MDP ? "mdp" : "trm", ep == MIPEMU_EP_MDP ? u : (unsigned)ep, len);
        return -1;
    }
    const mipemu_config *c = &net->cfg;
    unsigned unit = req[6];
    unsigned tid = get16(req);
    const uint8_t *pdu = req + 7;
    size_t plen = len - 7;
    unsigned fc = pdu[0];
    const map_t *m = ep == MIPEMU_EP_MDP ? &MDP_MAP : &TRM_MAP;
    int sidx = ep == MIPEMU_EP_MDP ? (int)unit - 1 : ep - 1;
    unsigned rmax = c->allow_127 ? 127 : 125;
    unsigned wmax16 = c->allow_127 ? 127 : 123;
    unsigned wmax23 = c->allow_127 ? 127 : 121;
    unsigned ra = 0, rq = 0, wa = 0, wq = 0;
    unsigned exc = 0;
    int clear_new = 0;
    long olen = 0;

    if (ep == MIPEMU_EP_MDP && (unit < 1 || unit > (unsigned)c->stations)) {
        exc = 0x0B;
        goto done;
    }
    station_t *s = &net->st[sidx];
    side_t *sd = ep == MIPEMU_EP_MDP ? &s->mdp : &s->trm;

    switch (fc) {
    case 3:
    case 4:
        if (plen != 5) { exc = 3; break; }
        ra = get16(pdu + 1);
        rq = get16(pdu + 3);
        if (rq < 1 || rq > rmax) { exc = 3; break; }
        if (!range_readable(m, ra, rq)) { exc = 2; break; }
        break;
    case 6:
        if (plen != 5) { exc = 3; break; }
        wa = get16(pdu + 1);
        wq = 1;
        if (!range_writable(m, wa, 1)) { exc = 2; break; }
        if (c->mode == MIPEMU_DYNAMIC) { exc = 2; break; } /* dynamic: only block writes from the first register */
        break;
    case 16:
        if (plen < 6) { exc = 3; break; }
        wa = get16(pdu + 1);
        wq = get16(pdu + 3);
        if (wq < 1 || wq > wmax16 || pdu[5] != 2 * wq || plen != 6 + 2 * (size_t)wq) { exc = 3; break; }
        if (!range_writable(m, wa, wq)) { exc = 2; break; }
        if (c->mode == MIPEMU_DYNAMIC && wa != m->wbase) { exc = 2; break; }
        break;
    case 23:
        if (plen < 10) { exc = 3; break; }
        ra = get16(pdu + 1);
        rq = get16(pdu + 3);
        wa = get16(pdu + 5);
        wq = get16(pdu + 7);
        if (rq < 1 || rq > rmax || wq < 1 || wq > wmax23 || pdu[9] != 2 * wq || plen != 10 + 2 * (size_t)wq) {
            exc = 3;
            break;
        }
        if (!range_readable(m, ra, rq) || !range_writable(m, wa, wq)) { exc = 2; break; }
        if (c->mode == MIPEMU_DYNAMIC && wa != m->wbase) { exc = 2; break; }
        break;
    default:
        exc = 1;
        break;
    }
    if (exc)
        goto done;

    /* execute: writes first (FC23 as the standard says), then reads; all in one call, so atomic
     * with respect to the radio, which only runs in mipemu_net_advance */
    memcpy(out, req, 7);
    out[7] = (uint8_t)fc;
    if (fc == 6) {
        apply_write(net, m, sd, wa, 1, pdu + 3);
        memcpy(out + 8, pdu + 1, 4);
        olen = 12;
    } else if (fc == 16) {
        apply_write(net, m, sd, wa, wq, pdu + 6);
        memcpy(out + 8, pdu + 1, 4);
        olen = 12;
    } else {
        if (fc == 23)
            apply_write(net, m, sd, wa, wq, pdu + 10);
        out[8] = (uint8_t)(2 * rq);
        if (is_status_read(m, ra, rq)) {
            put16(out + 9, sd->rstat);
            if (rq > 1)
                put16(out + 11, sd->rd_count);
            for (unsigned i = 2; i < rq; i++)
                put16(out + 9 + 2 * i, sd->rd[i - 2]);
        } else {
            for (unsigned i = 0; i < rq; i++)
                put16(out + 9 + 2 * i, get_reg(m, s, sd, ra + i));
        }
        olen = 9 + 2 * (long)rq;
        clear_new = touches_read_area(m, ra, rq);
    }
    put16(out + 4, (unsigned)(olen - 6));
    if (clear_new)
        sd->rstat &= (uint16_t)~MIPEMU_RS_NEW_DATA; /* after the response was composed */

done:
    if (exc)
        olen = exception_reply(out, req, fc, exc);
    if (net->trace) { /* the line costs two formats per request: only when someone reads it */
        char extra[96] = "";
        if ((fc == 6 || fc == 16 || fc == 23) && !exc) {
            const uint8_t *v = fc == 6 ? pdu + 3 : fc == 16 ? pdu + 6 : pdu + 10;
            snprintf(extra, sizeof extra, ",\"wa\":%u,\"wq\":%u,\"w0\":%u", wa, wq, get16(v));
        } else if (fc == 6 || fc == 16 || fc == 23) {
            snprintf(extra, sizeof extra, ",\"wa\":%u,\"wq\":%u", wa, wq);
        }
        char rd[64] = "";
        if ((fc == 3 || fc == 4 || fc == 23) && rq)
            snprintf(rd, sizeof rd, ",\"ra\":%u,\"rq\":%u", ra, rq);
        if (ep == MIPEMU_EP_MDP)
            emit(net, net->now, "\"ev\":\"modbus\",\"ep\":\"mdp\",\"st\":%u,\"unit\":%u,\"tid\":%u,\"fc\":%u%s%s,\"exc\":%u",
                 unit, unit, tid, fc, rd, extra, exc);
        else
            emit(net, net->now, "\"ev\":\"modbus\",\"ep\":\"trm\",\"st\":%d,\"unit\":%u,\"tid\":%u,\"fc\":%u%s%s,\"exc\":%u",
                 ep, unit, tid, fc, rd, extra, exc);
    }
    return olen;
}

/* ---- test access ---- */

/* The buffers of endpoint ep as a Modbus client addresses them: NULL for a bad endpoint or unit. */
static station_t *station_of(const mipemu_net *net, int ep, int unit)
{
    if (!net || ep < 0 || ep > net->cfg.stations)
        return NULL;
    int s = ep == MIPEMU_EP_MDP ? unit : ep;
    if (s < 1 || s > net->cfg.stations)
        return NULL;
    return &net->st[s - 1];
}

int mipemu_net_inject(mipemu_net *net, int ep, int unit, const uint16_t *blk, int len)
{
    station_t *s = station_of(net, ep, unit);
    if (!s || !blk || len < 1 || len > AREA)
        return -1;
    side_t *sd = ep == MIPEMU_EP_MDP ? &s->mdp : &s->trm;
    memcpy(sd->rd, blk, (size_t)len * sizeof *blk);
    sd->rd_count = (uint16_t)len;
    sd->rstat |= MIPEMU_RS_NEW_DATA;
    emit(net, net->now, "\"ev\":\"inject\",\"ep\":\"%s\",\"st\":%d,\"regs\":%d,\"r0\":%u",
         ep == MIPEMU_EP_MDP ? "mdp" : "trm", (int)(s - net->st) + 1, len, (unsigned)blk[0]);
    return 0;
}

int mipemu_net_peek(const mipemu_net *net, int ep, int unit, unsigned addr, unsigned n, uint16_t *out)
{
    const station_t *s = station_of(net, ep, unit);
    if (!s || !out)
        return -1;
    const map_t *m = ep == MIPEMU_EP_MDP ? &MDP_MAP : &TRM_MAP;
    const side_t *sd = ep == MIPEMU_EP_MDP ? &s->mdp : &s->trm;
    if (n > 0xFFFF || !range_readable(m, addr, n))
        return -1;
    for (unsigned i = 0; i < n; i++)
        out[i] = get_reg(m, s, sd, addr + i);
    return 0;
}
