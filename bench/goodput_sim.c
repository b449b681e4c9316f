/* goodput_sim: FALLBACK measurement of the goodput figure, used only while the co-simulation
 * (cosim/) is not built. The emulator core (libmipemu) in virtual time with two SCRIPTED
 * applications in C standing in for the PLCs running st_lib (not the ST blocks themselves):
 *
 *   outstation: every scan, one FC3 read of 125 registers at TRM 2198; when "new read data"
 *     shows the acknowledgement of the record in flight, it writes the next record
 *     (FC16 at 2001: record number + PAYLOAD registers);
 *   central: every scan, one FC3 read of 125 registers at MDP 198 (unit 1); a new record
 *     (number = last + 1) is accepted and acknowledged (FC16 of one register at MDP 10),
 *     a duplicate is acknowledged again.
 *
 *   goodput_sim LOSS SEED RECORDS [TICK_MS BITRATE GAP_MS PAYLOAD]
 *
 * Runs until the sender has the acknowledgement of the last record (as the co-simulation's
 * "finished"), then prints one line: polls=P records=R payload=N dups=D virtual_s=T
 * Errors: one line on stderr, exit 2 (bad arguments) or 1. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mipemu.h"

static mipemu_net *net;
static unsigned tid;

static int request(int ep, int unit, const uint8_t *pdu, int pdulen, uint16_t *regs, int nregs)
{
    uint8_t q[300], r[MIPEMU_RESPONSE_MAX];
    tid++;
    q[0] = (uint8_t)(tid >> 8); q[1] = (uint8_t)tid; q[2] = 0; q[3] = 0;
    q[4] = (uint8_t)((pdulen + 1) >> 8); q[5] = (uint8_t)(pdulen + 1); q[6] = (uint8_t)unit;
    memcpy(q + 7, pdu, (size_t)pdulen);
    long n = mipemu_handle(net, ep, q, (size_t)(7 + pdulen), r, sizeof r);
    if (n < 9 || (r[7] & 0x80)) {
        fprintf(stderr, "goodput_sim: error: request fc %d to endpoint %d failed (%s %d)\n", pdu[0],
                ep, n < 9 ? "length" : "exception", n < 9 ? (int)n : r[8]);
        exit(1);
    }
    for (int i = 0; i < nregs; i++)
        regs[i] = (uint16_t)(r[9 + 2 * i] << 8 | r[10 + 2 * i]);
    return 0;
}

static void read125(int ep, int unit, int addr, uint16_t *regs)
{
    uint8_t p[5] = {3, (uint8_t)(addr >> 8), (uint8_t)addr, 0, 125};
    request(ep, unit, p, 5, regs, 125);
}

static void write_block(int ep, int unit, int addr, const uint16_t *v, int n)
{
    uint8_t p[6 + 2 * 123];
    p[0] = 16; p[1] = (uint8_t)(addr >> 8); p[2] = (uint8_t)addr; p[3] = 0; p[4] = (uint8_t)n;
    p[5] = (uint8_t)(2 * n);
    for (int i = 0; i < n; i++) {
        p[6 + 2 * i] = (uint8_t)(v[i] >> 8);
        p[7 + 2 * i] = (uint8_t)v[i];
    }
    request(ep, unit, p, 6 + 2 * n, NULL, 0);
}

static double num(const char *s, const char *what, double lo, double hi)
{
    char *end;
    double v = strtod(s, &end);
    if (*end || end == s || v < lo || v > hi) {
        fprintf(stderr, "goodput_sim: error: %s must be %g..%g, got '%s'\n", what, lo, hi, s);
        exit(2);
    }
    return v;
}

int main(int argc, char **argv)
{
    if (argc != 4 && argc != 8) {
        fprintf(stderr, "usage: goodput_sim LOSS SEED RECORDS [TICK_MS BITRATE GAP_MS PAYLOAD]\n");
        return 2;
    }
    mipemu_config c;
    mipemu_config_default(&c);
    c.loss_down = c.loss_up = num(argv[1], "LOSS", 0, 0.95);
    c.seed = (uint64_t)num(argv[2], "SEED", 0, 1e15);
    long records = (long)num(argv[3], "RECORDS", 1, 65534);
    double tick_ms = argc == 8 ? num(argv[4], "TICK_MS", 0.001, 10000) : 10;
    if (argc == 8) {
        c.bitrate = (uint32_t)num(argv[5], "BITRATE", 300, 1e7);
        c.slot_gap_ns = (uint64_t)(num(argv[6], "GAP_MS", 0, 10000) * 1e6);
    }
    int payload = argc == 8 ? (int)num(argv[7], "PAYLOAD", 1, 122) : 122;
    char err[160];
    net = mipemu_net_new(&c, err, sizeof err);
    if (!net) {
        fprintf(stderr, "goodput_sim: error: %s\n", err);
        return 2;
    }
    uint64_t tick = (uint64_t)(tick_ms * 1e6), t = 0;
    uint16_t rd[125], blk[123];
    long cur = 1, last = 0, accepted = 0, dups = 0, payload_regs = 0;
    int finished = 0; /* the sender has the acknowledgement of the last record */
    mipemu_stats st0, st1;

    blk[0] = 1;
    for (int i = 1; i <= payload; i++)
        blk[i] = (uint16_t)i;
    write_block(1, 1, 2001, blk, payload + 1);
    mipemu_net_stats(net, 1, &st0);
    /* at most 1000 virtual seconds per record: a stuck chain fails instead of looping */
    uint64_t limit = (uint64_t)records * 1000000000000ull;
    while (!finished && t < limit) {
        t += tick;
        mipemu_net_advance(net, t);
        /* central */
        read125(MIPEMU_EP_MDP, 1, 198, rd);
        if ((rd[0] & MIPEMU_RS_NEW_DATA) && rd[1] >= 1) {
            uint16_t n = rd[2];
            if (n == (uint16_t)(last + 1)) {
                accepted++;
                payload_regs += rd[1] - 1;
                last = n;
                write_block(MIPEMU_EP_MDP, 1, 10, &n, 1);
            } else if (n == (uint16_t)last) {
                dups++;
                write_block(MIPEMU_EP_MDP, 1, 10, &n, 1);
            }
        }
        /* outstation */
        read125(1, 1, 2198, rd);
        if ((rd[0] & MIPEMU_RS_NEW_DATA) && rd[1] >= 1 && rd[2] == (uint16_t)cur) {
            if (cur == records) {
                finished = 1;
                break;
            }
            cur++;
            blk[0] = (uint16_t)cur;
            write_block(1, 1, 2001, blk, payload + 1);
        }
    }
    mipemu_net_stats(net, 1, &st1);
    if (!finished) {
        fprintf(stderr, "goodput_sim: error: only %ld of %ld records acknowledged\n", accepted, records);
        return 1;
    }
    printf("polls=%llu records=%ld payload=%ld dups=%ld virtual_s=%.3f\n",
           (unsigned long long)(st1.polls - st0.polls), accepted, payload_regs, dups, t / 1e9);
    mipemu_net_free(net);
    return 0;
}
