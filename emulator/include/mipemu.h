/* mipemu: an emulated Piciorgros MIP radio network (1 MDP-810 central + N TRM-810 outstations).
 *
 * The core is pure: no sockets, no clocks, no global state. A caller moves Modbus TCP frames
 * in and out (mipemu_handle) and moves virtual time forward (mipemu_net_advance); the radio
 * model runs only inside mipemu_net_advance. Randomness comes from the configured seed only,
 * so the same seed, the same requests at the same virtual times give the same trace bytes.
 * Several networks may live in one process. Not thread-safe per network.
 *
 * Register maps, status bits and the radio timing formula: emulator/README.md. */
#ifndef MIPEMU_H
#define MIPEMU_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MIPEMU_MAX_STATIONS 247
#define MIPEMU_AREA_REGS 148           /* write area and read area, per direction */
#define MIPEMU_MBAP_LEN_MAX 1024       /* larger MBAP length field: malformed, connection closed */
#define MIPEMU_FRAME_MAX (6 + MIPEMU_MBAP_LEN_MAX)
#define MIPEMU_RESPONSE_MAX 300        /* enough for any response (127 registers + MBAP) */

enum mipemu_mode { MIPEMU_DYNAMIC = 0, MIPEMU_STATIC = 1 };

/* Endpoint numbers for mipemu_handle: 0 is the MDP-810, 1..N the TRM-810 of station 1..N. */
#define MIPEMU_EP_MDP 0

/* Read-status bits (MDP register 2/198, TRM register 2198). */
#define MIPEMU_RS_NEW_DATA 0x0001
#define MIPEMU_RS_WRITE_WAITING 0x0002
#define MIPEMU_RS_WRITE_UNCONFIRMED 0x0010

/* Station-status bits (MDP register 1, per station). */
#define MIPEMU_ST_ANSWERED 0x0001    /* the station answered the last poll */
#define MIPEMU_ST_UNREACHABLE 0x0002 /* the last fail_polls polls went unanswered */
#define MIPEMU_ST_EVER_ANSWERED 0x0004 /* answered at least once since start */
#define MIPEMU_ST_DOWN_RESEND 0x0008 /* a downlink block was sent and is being repeated */

typedef struct mipemu_config {
    int stations;               /* 1..247; station addresses are 1..stations */
    int mode;                   /* MIPEMU_DYNAMIC or MIPEMU_STATIC */
    int static_registers;       /* static mode: N mirrored registers, 1..148 */
    double loss_down;           /* probability a MDP->station telegram is lost, 0..1 */
    double loss_up;             /* probability a station->MDP telegram is lost, 0..1 */
    double burst;               /* 0: independent losses; >= 1: Gilbert-Elliott, mean burst length in telegrams */
    uint64_t seed;
    uint32_t bitrate;           /* radio bit rate, bit/s, 300..10000000 */
    uint64_t slot_gap_ns;       /* turnaround gap after every telegram */
    int overhead_bytes;         /* per telegram: preamble, sync, header, CRC; 1..255 */
    int fail_polls;             /* unanswered polls in a row before "not reachable", 1..255 */
    int allow_127;              /* accept up to 127 registers per request (the device's limit) */
    int lose_record;            /* scripted fault: the first uplink block whose register 0 equals
                                   this value is lost once per station (1..65535; 0 = off). The
                                   note's example (record 2 lost on the way) is lose_record = 2. */
} mipemu_config;

typedef struct mipemu_net mipemu_net;

/* Per-station radio counters, for tests and benchmarks. */
typedef struct mipemu_stats {
    uint64_t polls;             /* slots started for this station */
    uint64_t tel_down, lost_down; /* MDP->station telegrams (polls and acks) sent / lost */
    uint64_t tel_up, lost_up;   /* station->MDP telegrams sent / lost */
    uint64_t blocks_down, blocks_up;     /* blocks delivered into the receiver's read area */
    uint64_t dup_down, dup_up;  /* of those, repeats of a block already delivered */
    uint64_t confirmed_down, confirmed_up; /* blocks whose confirmation reached the sender */
} mipemu_stats;

typedef void (*mipemu_trace_fn)(void *user, const char *line, size_t len);

/* Fills c with the defaults documented in README.md (1 station, dynamic, no loss, 9600 bit/s...). */
void mipemu_config_default(mipemu_config *c);

/* Returns NULL when the configuration is invalid (errmsg, if given, gets a one-line reason)
 * or memory is short. */
mipemu_net *mipemu_net_new(const mipemu_config *c, char *errmsg, size_t errmsg_size);
void mipemu_net_free(mipemu_net *net);

/* Trace: fn receives one JSON object per line, newline included, stamped in virtual ns. */
void mipemu_net_set_trace(mipemu_net *net, mipemu_trace_fn fn, void *user);
/* One more trace line at the core's virtual now, with the next "seq": {"t":..,"seq":..,FIELDS}.
 * For what the core does not see but a reader wants beside its lines in time order (the
 * server's relay); FIELDS is JSON members without braces. Nothing when no trace is set. */
void mipemu_net_trace_note(mipemu_net *net, const char *fields);

/* Runs the radio model up to virtual time now_ns. Returns 0, or -1 if now_ns lies before the
 * time already reached (nothing is done then). */
int mipemu_net_advance(mipemu_net *net, uint64_t now_ns);
uint64_t mipemu_net_now(const mipemu_net *net);
/* Virtual time of the next radio event (the end of the telegram or gap in progress). */
uint64_t mipemu_net_next_event(const mipemu_net *net);

/* Frame length from the first bytes of a Modbus TCP stream: 0 = need more bytes (fewer than 7),
 * > 0 = total length of the frame (MBAP + PDU), -1 = malformed header (protocol id not 0,
 * length field < 2 or > MIPEMU_MBAP_LEN_MAX): close the connection. */
long mipemu_frame_length(const uint8_t *buf, size_t len);

/* One Modbus TCP request (a whole frame) to endpoint ep (MIPEMU_EP_MDP or a station 1..N).
 * Writes the response frame into out (out_cap >= MIPEMU_RESPONSE_MAX) and returns its length;
 * returns -1 when the connection must be closed (malformed frame, bad endpoint). A malformed
 * frame is traced as a "modbus" line with "close"; pass what was received to get that line. */
long mipemu_handle(mipemu_net *net, int ep, const uint8_t *req, size_t req_len,
                   uint8_t *out, size_t out_cap);

int mipemu_net_stations(const mipemu_net *net);
/* Returns 0, or -1 for an unknown station. */
int mipemu_net_stats(const mipemu_net *net, int station, mipemu_stats *out);

/* Scripted per-telegram faults, for tests (README.md, "Scripted faults"). The hook is called once
 * for each telegram that carries a data block, when its fate is decided: the poll carrying the
 * MDP's block for the station (up = 0) and the answer carrying the station's block (up = 1); blk
 * is the block (len registers, valid during the call only). It is called from inside
 * mipemu_net_advance: it may read the network (mipemu_net_stats, mipemu_net_peek) but must not
 * change it (no mipemu_handle, inject or advance). Its verdict applies on top of the
 * random loss model (whose draws it does not change) and of lose_record: */
enum mipemu_fate {
    MIPEMU_FATE_OK = 0,   /* as the loss model decides */
    MIPEMU_FATE_LOST = 1, /* the telegram is lost, as by the loss model: not delivered, not
                             confirmed, sent again at the next poll. A lost answer also loses the
                             confirmation of the poll's block it carries; a lost poll gets no answer */
    MIPEMU_FATE_DUP = 2,  /* delivered, but its confirmation is lost (uplink: the ack; downlink:
                             only the confirmation part of the answer, whose block still arrives):
                             the block stays pending, bit 4 set, and is delivered again at the next poll */
    MIPEMU_FATE_DROP = 3  /* confirmed to the sender but never delivered: not physical (the device
                             confirms only what the peer received), for tests of what depends on that */
};
typedef int (*mipemu_fate_fn)(void *user, int station, int up, const uint16_t *blk, int len);
/* fn NULL: no hook (the default). Other return values than the four above count as OK. */
void mipemu_net_set_fate(mipemu_net *net, mipemu_fate_fn fn, void *user);

/* Scripted reception, for tests: the read area of endpoint ep (MIPEMU_EP_MDP with the station
 * in unit, or a station 1..N) receives blk (1..148 registers) as if the radio had delivered it
 * (the first len registers, the count, bit 0 set); no telegram, no counter. Traced as "inject".
 * Returns 0, or -1 for a bad endpoint, unit or length. */
int mipemu_net_inject(mipemu_net *net, int ep, int unit, const uint16_t *blk, int len);

/* Reads n registers from addr of endpoint ep (unit as for mipemu_handle's MDP unit id) without
 * side effects (a Modbus read of the read area would clear "new data"), for tests and tools.
 * Returns 0, or -1 for a bad endpoint or unit, or a register outside the map. */
int mipemu_net_peek(const mipemu_net *net, int ep, int unit, unsigned addr, unsigned n, uint16_t *out);

/* Radio timing: air time of a telegram carrying nregs registers, in ns (see README.md). */
uint64_t mipemu_telegram_ns(const mipemu_config *c, int nregs);

#ifdef __cplusplus
}
#endif
#endif
