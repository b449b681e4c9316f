/* libFuzzer target: the slave's request path. Each input is the byte stream of one client
 * connection (one end of a socketpair given to the slave like an accepted TCP client); the
 * slave frames, decodes and answers it in virtual mode until the client's EOF closes it.
 * Checks: no crash / sanitizer report, every reply is one well-formed Modbus TCP ADU that
 * echoes a transaction id, and the connection is closed in the end. */
#include "plcrt.h"

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

static plcrt_t *rt;

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    char err[256];
    rt = plcrt_new(plcrt_linked_program(), err, sizeof err);
    if (!rt || plcrt_slave_start(rt, "127.0.0.1", 0) != 0) {
        fprintf(stderr, "fuzz_slave: cannot start: %s\n", rt ? plcrt_errmsg(rt) : err);
        abort();
    }
    plcrt_set_log(rt, NULL, NULL);
    return 0;
}

static int get16(const uint8_t *p) { return (p[0] << 8) | p[1]; }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > 16384) return 0; /* more than the socket buffer: not what this target is for */
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0) abort();
    int bufsz = 1 << 16;
    setsockopt(sv[1], SOL_SOCKET, SO_SNDBUF, &bufsz, sizeof bufsz);
    if (plcrt_slave_add_client(rt, sv[0]) != 0) abort();
    fcntl(sv[1], F_SETFL, O_NONBLOCK);
    size_t off = 0;
    uint8_t in[8192];
    size_t in_len = 0;
    plcrt_slave_stats_t st;
    int closed = 0;
    for (int i = 0; i < 100000 && !closed; i++) {
        if (off < size) {
            ssize_t k = write(sv[1], data + off, size - off);
            if (k > 0) off += (size_t)k;
            if (off == size) shutdown(sv[1], SHUT_WR);
        } else if (size == 0 && i == 0) {
            shutdown(sv[1], SHUT_WR);
        }
        plcrt_slave_poll(rt, 0);
        for (;;) {
            ssize_t k = read(sv[1], in + in_len, sizeof in - in_len);
            if (k > 0) { in_len += (size_t)k; continue; }
            if (k == 0) closed = 1;
            break;
        }
        /* every complete reply: protocol 0, length matching, a function code and data */
        size_t p = 0;
        while (in_len - p >= 7 && in_len - p >= (size_t)(6 + get16(in + p + 4))) {
            int len = get16(in + p + 4);
            if (get16(in + p + 2) != 0 || len < 3 || len > 254) abort();
            int fc = in[p + 7];
            if ((fc & 0x80) && (len != 3 || in[p + 8] < 1 || in[p + 8] > 3)) abort();
            p += (size_t)(6 + len);
        }
        memmove(in, in + p, in_len - p);
        in_len -= p;
        if (in_len > 300) abort(); /* a reply longer than any ADU */
    }
    if (!closed) abort(); /* the slave must close a connection whose client is gone */
    plcrt_slave_stats(rt, &st);
    if (st.clients != 0) abort();
    close(sv[1]);
    return 0;
}
