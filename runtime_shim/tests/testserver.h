/* A small libmodbus test server on 127.0.0.1 (or one end of a socketpair) for the C tests
 * and the benchmark: 200 holding / 200 input registers, 64 coils, a log of requests. */
#ifndef TESTSERVER_H
#define TESTSERVER_H

#include <arpa/inet.h>
#include <modbus.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#pragma GCC diagnostic ignored "-Wunused-function"


#define SRV_LOG 256
typedef struct server {
    modbus_t *ctx;
    modbus_mapping_t *map;
    int listen_fd, port;
    int client;
    pthread_t thread;
    volatile int stop;
    volatile int mute; /* receive, never answer (timeout tests) */
    pthread_mutex_t lock;
    int n_log;
    int log_fc[SRV_LOG], log_addr[SRV_LOG], log_count[SRV_LOG], log_unit[SRV_LOG];
} server_t;

static void server_record(server_t *s, const uint8_t *q, int hl)
{
    pthread_mutex_lock(&s->lock);
    if (s->n_log < SRV_LOG) {
        s->log_fc[s->n_log] = q[hl];
        s->log_addr[s->n_log] = (q[hl + 1] << 8) | q[hl + 2];
        s->log_count[s->n_log] = (q[hl + 3] << 8) | q[hl + 4];
        s->log_unit[s->n_log] = q[hl - 1];
        s->n_log++;
    }
    pthread_mutex_unlock(&s->lock);
}

/* serves one request on fd; -1 when the peer closed */
static int server_serve_fd(server_t *s, int fd)
{
    uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
    modbus_set_socket(s->ctx, fd);
    int rc = modbus_receive(s->ctx, q);
    if (rc <= 0) return rc;
    server_record(s, q, modbus_get_header_length(s->ctx));
    if (s->mute) return 1;
    pthread_mutex_lock(&s->lock);
    rc = modbus_reply(s->ctx, q, rc, s->map);
    pthread_mutex_unlock(&s->lock);
    return rc < 0 ? -1 : 1;
}

static void *server_thread(void *arg)
{
    server_t *s = arg;
    while (!s->stop) {
        fd_set rd;
        FD_ZERO(&rd);
        int maxfd = s->listen_fd;
        FD_SET(s->listen_fd, &rd);
        if (s->client >= 0) {
            FD_SET(s->client, &rd);
            if (s->client > maxfd) maxfd = s->client;
        }
        struct timeval tv = {0, 20000};
        if (select(maxfd + 1, &rd, NULL, NULL, &tv) <= 0) continue;
        if (FD_ISSET(s->listen_fd, &rd)) {
            int c = accept(s->listen_fd, NULL, NULL);
            if (c >= 0) {
                if (s->client >= 0) close(s->client);
                s->client = c;
            }
            continue;
        }
        if (s->client >= 0 && FD_ISSET(s->client, &rd) && server_serve_fd(s, s->client) < 0) {
            close(s->client);
            s->client = -1;
        }
    }
    return NULL;
}

/* A libmodbus server with 200 holding registers, 200 input registers, 64 coils. */
static server_t *server_new(int with_listener)
{
    server_t *s = calloc(1, sizeof *s);
    s->ctx = modbus_new_tcp("127.0.0.1", 1502);
    s->map = modbus_mapping_new(64, 64, 200, 200);
    modbus_set_indication_timeout(s->ctx, 1, 0);
    pthread_mutex_init(&s->lock, NULL);
    s->client = -1;
    s->listen_fd = -1;
    if (with_listener) {
        struct sockaddr_in a = {0};
        a.sin_family = AF_INET;
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        s->listen_fd = socket(AF_INET, SOCK_STREAM, 0);
        bind(s->listen_fd, (struct sockaddr *)&a, sizeof a);
        listen(s->listen_fd, 4);
        socklen_t len = sizeof a;
        getsockname(s->listen_fd, (struct sockaddr *)&a, &len);
        s->port = ntohs(a.sin_port);
        pthread_create(&s->thread, NULL, server_thread, s);
    }
    return s;
}

static void server_free(server_t *s)
{
    if (s->listen_fd >= 0) {
        s->stop = 1;
        pthread_join(s->thread, NULL);
        close(s->listen_fd);
    }
    if (s->client >= 0) close(s->client);
    modbus_set_socket(s->ctx, -1);
    modbus_free(s->ctx);
    modbus_mapping_free(s->map);
    free(s);
}

static int server_count(server_t *s, int fc)
{
    pthread_mutex_lock(&s->lock);
    int n = 0;
    for (int i = 0; i < s->n_log; i++) n += s->log_fc[i] == fc;
    pthread_mutex_unlock(&s->lock);
    return n;
}

#endif
