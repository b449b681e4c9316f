/* siprotec: an emulated SIPROTEC event recorder (Ereignisschreiber) read over Modbus with the
 * SOE_Control handshake. A pure core like mipemu: no clocks, no sockets, no global state; time
 * comes from the caller (virtual ns). The facts, their sources and what is our choice:
 * docs/chain.md, "The relay (SIPROTEC event recorder)". */
#ifndef SIPROTEC_H
#define SIPROTEC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SIPROTEC_BLOCKS 3        /* message blocks per read (SIPROTEC 5 manual 5.2.4) */
#define SIPROTEC_BLOCK_REGS 8    /* type/bit, address, cause/type, value, 4 time stamp */
#define SIPROTEC_MAP_REGS (2 + SIPROTEC_BLOCKS * SIPROTEC_BLOCK_REGS) /* 40601..40626 */
#define SIPROTEC_RESPONSE_MAX 260

enum { SIPROTEC_OVF_DROP_OLDEST = 0, SIPROTEC_OVF_DROP_NEW = 1 };
enum { SIPROTEC_BAD_ACK_EXC03 = 0, SIPROTEC_BAD_ACK_IGNORE = 1 };

typedef struct siprotec_config {
    uint16_t base;           /* PDU address of "number of entries" (reference 40601 -> 600) */
    uint32_t capacity;       /* entries the recorder holds (>= 3) */
    int overflow;            /* SIPROTEC_OVF_*: which entry goes when a new one finds it full */
    int seq_bits;            /* width of the sequence number in SOE_Control bits 0.. (2..8) */
    int bad_ack;             /* SIPROTEC_BAD_ACK_*: the answer to a wrong acknowledgement */
    double rate;             /* generated events per second, evenly spaced; 0 = none */
    uint32_t burst_n;        /* every burst_every_s: burst_n events at once; 0 = none */
    double burst_every_s;
    uint64_t time_origin_ms; /* time stamp (ms since 1970 UTC) of virtual time 0 */
} siprotec_config;

typedef struct siprotec_stats {
    uint32_t entries;        /* in the recorder, not yet acknowledged */
    uint64_t generated;      /* events that reached the recorder (scripted and generated) */
    uint64_t dropped;        /* lost to overflow */
    uint64_t acknowledged;   /* deleted by acknowledgements */
    uint64_t reset_cleared;  /* deleted by "reset list" */
    uint64_t bad_acks;       /* acknowledgements refused (wrong sequence number or count) */
    uint16_t seq;            /* sequence number now */
    uint16_t offered;        /* message blocks offered now (0..3) */
} siprotec_stats;

typedef struct siprotec_relay siprotec_relay;

void siprotec_config_default(siprotec_config *c);
/* NULL and a one-line reason in err when the configuration is invalid */
siprotec_relay *siprotec_new(const siprotec_config *c, char *err, size_t errlen);
void siprotec_free(siprotec_relay *r);

/* A scripted event at virtual time t_ns: w = register type / bit offset, register address,
 * message cause / indication type, value. Returns 0, or -1 when out of memory. */
int siprotec_script(siprotec_relay *r, uint64_t t_ns, const uint16_t w[4]);
/* Lets the events up to now_ns (never backwards) reach the recorder. */
void siprotec_advance(siprotec_relay *r, uint64_t now_ns);
/* Virtual time of the next event, UINT64_MAX if none. */
uint64_t siprotec_next_event(const siprotec_relay *r);

/* One Modbus TCP request ADU (MBAP + PDU) -> the response ADU in resp; returns its length, or -1
 * when the frame is malformed (the caller closes the connection). cap >= SIPROTEC_RESPONSE_MAX. */
long siprotec_handle(siprotec_relay *r, const uint8_t *req, size_t len, uint8_t *resp, size_t cap);
/* The register image without side effects: n registers from PDU address addr (0 outside). */
void siprotec_peek(const siprotec_relay *r, uint16_t addr, unsigned n, uint16_t *out);
void siprotec_get_stats(const siprotec_relay *r, siprotec_stats *s);

#ifdef __cplusplus
}
#endif
#endif
