/* libFuzzer harness over the request path of the mipemu core: the byte stream is cut into frames
 * by mipemu_frame_length exactly as the server does, every frame goes through mipemu_handle, and
 * radio time advances in between. Responses and trace lines are checked for well-formedness.
 *
 * Input: byte 0 = configuration flags, byte 1 = static register count, then operations:
 *   op & 3 == 0 or 1: feed the next (next byte) bytes into the stream of endpoint
 *                     (op >> 2) mod (stations + 2); the last one is the SIPROTEC relay
 *   op & 3 == 2:      advance virtual time by (next byte) * 7 ms
 *   op & 3 == 3:      advance to the next radio event */
#include "mipemu.h"
#include "siprotec.h"

#include <stdlib.h>
#include <string.h>

#define MAX_EP (4 + 2)

typedef struct { uint8_t buf[2 * MIPEMU_FRAME_MAX]; size_t len; } stream_t;

static void check_trace(void *user, const char *line, size_t len)
{
    (void)user;
    if (len < 3 || line[0] != '{' || line[len - 2] != '}' || line[len - 1] != '\n' || memchr(line, 0, len))
        abort();
}

static void check_response(const uint8_t *req, const uint8_t *r, long rl)
{
    if (rl < 9 || rl > MIPEMU_RESPONSE_MAX)
        abort();
    if (memcmp(r, req, 4) != 0 || r[6] != req[6])       /* tid, protocol, unit echoed */
        abort();
    if (((long)r[4] << 8 | r[5]) != rl - 6)
        abort();
    /* function codes >= 0x80 are never supported, so their answer is always an exception */
    int is_exc = r[7] == (req[7] | 0x80) && (req[7] >= 0x80 || r[7] != req[7]);
    if (!is_exc && r[7] != req[7])
        abort();
    if (is_exc) {
        if (rl != 9 || !(r[8] == 1 || r[8] == 2 || r[8] == 3 || r[8] == 0x0B))
            abort();
    } else if (r[7] == 3 || r[7] == 4 || r[7] == 23) {
        if (rl != 9 + r[8])
            abort();
    } else if (rl != 12) {
        abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    mipemu_config c;
    mipemu_config_default(&c);
    uint8_t f = data[0];
    c.stations = 1 + (f & 3);
    c.mode = (f >> 2) & 1 ? MIPEMU_STATIC : MIPEMU_DYNAMIC;
    c.allow_127 = (f >> 3) & 1;
    c.loss_down = ((f >> 4) & 1) * 0.4;
    c.loss_up = ((f >> 5) & 1) * 0.3;
    c.burst = (f >> 6) & 1 ? 3.0 : 0.0;
    c.fail_polls = 1 + (f >> 7);
    c.static_registers = 1 + data[1] % MIPEMU_AREA_REGS;
    c.seed = size;
    c.bitrate = 19200;
    c.slot_gap_ns = 5000000;
    mipemu_net *net = mipemu_net_new(&c, NULL, 0);
    if (!net)
        abort();
    mipemu_net_set_trace(net, check_trace, NULL);
    /* the relay: its configuration from byte 1 too */
    siprotec_config rc;
    siprotec_config_default(&rc);
    rc.capacity = 3 + data[1] % 8;
    rc.overflow = (data[1] >> 6) & 1;
    rc.bad_ack = data[1] >> 7;
    rc.seq_bits = 2 + (data[1] >> 3) % 7;
    rc.rate = 50;
    rc.burst_n = 4;
    rc.burst_every_s = 0.3;
    siprotec_relay *relay = siprotec_new(&rc, NULL, 0);
    if (!relay)
        abort();
    int relay_ep = c.stations + 1;
    static stream_t st[MAX_EP];
    for (int i = 0; i < MAX_EP; i++)
        st[i].len = 0;
    uint64_t now = 0;
    size_t i = 2;
    while (i < size) {
        uint8_t op = data[i++];
        if ((op & 3) <= 1) {
            int ep = (op >> 2) % (c.stations + 2);
            size_t n = i < size ? data[i++] : 0;
            if (n > size - i)
                n = size - i;
            stream_t *s = &st[ep];
            if (n > sizeof s->buf - s->len)
                n = sizeof s->buf - s->len;
            memcpy(s->buf + s->len, data + i, n);
            s->len += n;
            i += n;
            size_t off = 0;
            for (;;) {
                long fl = mipemu_frame_length(s->buf + off, s->len - off);
                if (ep == relay_ep) {
                    if (fl == 0 || (fl > 0 && (size_t)fl > s->len - off))
                        break;
                    uint8_t out[SIPROTEC_RESPONSE_MAX];
                    long rl = siprotec_handle(relay, s->buf + off, fl < 0 ? s->len - off : (size_t)fl, out, sizeof out);
                    if (fl < 0 || rl < 0) {
                        if (fl < 0 && rl != -1)
                            abort();
                        s->len = off = 0;
                        break;
                    }
                    check_response(s->buf + off, out, rl);
                    siprotec_stats rs;
                    siprotec_get_stats(relay, &rs);
                    if (rs.entries > rc.capacity || rs.offered > 3 || rs.offered > rs.entries)
                        abort();
                    off += (size_t)fl;
                    continue;
                }
                if (fl < 0) {            /* malformed: the core traces it, the connection closes */
                    uint8_t out[MIPEMU_RESPONSE_MAX];
                    if (mipemu_handle(net, ep, s->buf + off, s->len - off, out, sizeof out) != -1)
                        abort();
                    s->len = off = 0;
                    break;
                }
                if (fl == 0 || (size_t)fl > s->len - off)
                    break;
                if (fl > MIPEMU_FRAME_MAX)
                    abort();
                uint8_t out[MIPEMU_RESPONSE_MAX];
                long rl = mipemu_handle(net, ep, s->buf + off, (size_t)fl, out, sizeof out);
                if (rl < 0) {
                    s->len = off = 0;
                    break;
                }
                check_response(s->buf + off, out, rl);
                off += (size_t)fl;
            }
            memmove(s->buf, s->buf + off, s->len - off);
            s->len -= off;
        } else if ((op & 3) == 2) {
            now += (uint64_t)(i < size ? data[i++] : 0) * 7000000ULL;
            if (mipemu_net_advance(net, now) != 0)
                abort();
            siprotec_advance(relay, now);
        } else {
            uint64_t t = mipemu_net_next_event(net);
            if (t < now)
                abort();
            now = t;
            mipemu_net_advance(net, now);
            siprotec_advance(relay, now);
        }
    }
    siprotec_free(relay);
    mipemu_net_free(net);
    return 0;
}
