/* mb_bare_server: the smallest libmodbus TCP server (modbus_reply over a 500-register holding
 * mapping), the baseline for the emulator's throughput.
 *
 *   mb_bare_server PORT        (0 = any free port)
 *
 * Listens on 127.0.0.1, prints "listening port=N" once, serves one client at a time until
 * SIGTERM / SIGINT. Errors: one line on stderr, exit 1 (2 for a bad command line). */
#include <arpa/inet.h>
#include <errno.h>
#include <modbus.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

int main(int argc, char **argv)
{
    char *end;
    long port = argc == 2 ? strtol(argv[1], &end, 10) : -1;
    if (argc != 2 || *end || port < 0 || port > 65535) {
        fprintf(stderr, "usage: mb_bare_server PORT (0..65535)\n");
        return 2;
    }
    signal(SIGPIPE, SIG_IGN);
    modbus_t *ctx = modbus_new_tcp("127.0.0.1", (int)port);
    modbus_mapping_t *map = modbus_mapping_new(0, 0, 500, 0);
    if (!ctx || !map) {
        fprintf(stderr, "mb_bare_server: error: %s\n", modbus_strerror(errno));
        return 1;
    }
    for (int i = 0; i < 500; i++)
        map->tab_registers[i] = (uint16_t)i;
    int s = modbus_tcp_listen(ctx, 1);
    if (s == -1) {
        fprintf(stderr, "mb_bare_server: error: listen on port %ld: %s\n", port, modbus_strerror(errno));
        return 1;
    }
    struct sockaddr_in a;
    socklen_t alen = sizeof a;
    if (getsockname(s, (struct sockaddr *)&a, &alen) == -1) {
        fprintf(stderr, "mb_bare_server: error: getsockname: %s\n", strerror(errno));
        return 1;
    }
    printf("listening port=%d\n", ntohs(a.sin_port));
    fflush(stdout);
    uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
    for (;;) {
        if (modbus_tcp_accept(ctx, &s) == -1) {
            fprintf(stderr, "mb_bare_server: error: accept: %s\n", modbus_strerror(errno));
            return 1;
        }
        for (;;) {
            int n = modbus_receive(ctx, q);
            if (n == -1)
                break;           /* client gone */
            if (n > 0)
                modbus_reply(ctx, q, n, map);
        }
        close(modbus_get_socket(ctx));
        modbus_set_socket(ctx, s);
    }
}
