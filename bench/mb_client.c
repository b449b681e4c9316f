/* mb_client: a libmodbus client that times a fixed number of FC3 reads.
 *
 *   mb_client HOST PORT UNIT ADDR QTY COUNT
 *
 * Connects once, does COUNT/10 (at least 10) warm-up reads, then COUNT reads of QTY holding
 * registers at ADDR, one at a time (each waits for its answer), and prints one line:
 *   requests=COUNT seconds=S rate=R
 * Errors: one line on stderr, exit 1 (2 for a bad command line). */
#include <errno.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static long arg(const char *s, const char *what, long lo, long hi)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || v < lo || v > hi) {
        fprintf(stderr, "mb_client: error: %s must be %ld..%ld, got '%s'\n", what, lo, hi, s);
        exit(2);
    }
    return v;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

int main(int argc, char **argv)
{
    if (argc != 7) {
        fprintf(stderr, "usage: mb_client HOST PORT UNIT ADDR QTY COUNT\n");
        return 2;
    }
    const char *host = argv[1];
    int port = (int)arg(argv[2], "PORT", 1, 65535);
    int unit = (int)arg(argv[3], "UNIT", 0, 255);
    int addr = (int)arg(argv[4], "ADDR", 0, 65535);
    int qty = (int)arg(argv[5], "QTY", 1, 125);
    long count = arg(argv[6], "COUNT", 1, 100000000);

    modbus_t *ctx = modbus_new_tcp(host, port);
    if (!ctx) {
        fprintf(stderr, "mb_client: error: modbus_new_tcp: %s\n", modbus_strerror(errno));
        return 1;
    }
    modbus_set_slave(ctx, unit);
    modbus_set_response_timeout(ctx, 2, 0);
    if (modbus_connect(ctx) == -1) {
        fprintf(stderr, "mb_client: error: connect %s:%d: %s\n", host, port, modbus_strerror(errno));
        modbus_free(ctx);
        return 1;
    }
    uint16_t regs[125];
    long warm = count / 10 < 10 ? 10 : count / 10;
    for (long i = 0; i < warm + count; i++) {
        static double t0;
        if (i == warm)
            t0 = now_s();
        int rc = modbus_read_registers(ctx, addr, qty, regs);
        if (rc != qty) {
            fprintf(stderr, "mb_client: error: read %d registers at %d (request %ld): %s\n", qty,
                    addr, i + 1, rc == -1 ? modbus_strerror(errno) : "short answer");
            modbus_close(ctx);
            modbus_free(ctx);
            return 1;
        }
        if (i == warm + count - 1) {
            double dt = now_s() - t0;
            printf("requests=%ld seconds=%.6f rate=%.1f\n", count, dt, count / dt);
        }
    }
    modbus_close(ctx);
    modbus_free(ctx);
    return 0;
}
