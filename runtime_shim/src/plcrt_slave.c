/* Modbus TCP slave exposing the image like OpenPLC: holding registers 0-1023 = %QW,
 * 1024-2047 = %MW, input registers = %IW, coils = %QX, discrete inputs = %IX (bit
 * n = %IX n/8.n%8). Virtual mode serves requests in each scan's I/O phase; real-time
 * mode in a thread that takes the image lock per request. */
#include "plcrt_internal.h"

#include <arpa/inet.h>
#include <errno.h>
#include <modbus.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#define MAX_CLIENTS 16
#define NBITS (PLCRT_IMAGE_SIZE * 8)

struct plcrt_slave {
    modbus_t *ctx;
    modbus_mapping_t *map;
    int listen_fd;
    int port;
    int clients[MAX_CLIENTS];
    int n_clients;
    pthread_t thread;
    int thread_running;
    volatile int stop;
};

void plcrt_slave_free(struct plcrt_slave *s)
{
    if (!s) return;
    for (int i = 0; i < s->n_clients; i++) close(s->clients[i]);
    if (s->listen_fd >= 0) close(s->listen_fd);
    if (s->ctx) {
        modbus_set_socket(s->ctx, -1);
        modbus_free(s->ctx);
    }
    if (s->map) modbus_mapping_free(s->map);
    free(s);
}

int plcrt_slave_start(plcrt_t *rt, const char *host, int port)
{
    if (rt->slave) {
        plcrt_seterr(rt, "the Modbus slave is already running on port %d", rt->slave->port);
        return -1;
    }
    struct plcrt_slave *s = calloc(1, sizeof *s);
    if (!s) { plcrt_seterr(rt, "out of memory"); return -1; }
    s->listen_fd = -1;
    /* libmodbus takes the port as a string service; bind it ourselves to allow port 0 */
    s->ctx = modbus_new_tcp(host, port ? port : 502);
    s->map = modbus_mapping_new_start_address(0, NBITS, 0, NBITS, 0, 2 * PLCRT_IMAGE_SIZE, 0,
                                              PLCRT_IMAGE_SIZE);
    if (!s->ctx || !s->map) {
        plcrt_seterr(rt, "slave: cannot create the Modbus context");
        plcrt_slave_free(s);
        return -1;
    }
    modbus_set_indication_timeout(s->ctx, 1, 0);
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_port = htons((uint16_t)port);
    if (inet_pton(AF_INET, host, &addr.sin_addr) != 1) {
        plcrt_seterr(rt, "slave: '%s' is not an IPv4 address", host);
        plcrt_slave_free(s);
        return -1;
    }
    s->listen_fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    int one = 1;
    setsockopt(s->listen_fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (s->listen_fd < 0 || bind(s->listen_fd, (struct sockaddr *)&addr, sizeof addr) != 0 ||
        listen(s->listen_fd, 8) != 0) {
        plcrt_seterr(rt, "slave: cannot listen on %s:%d: %s", host, port, strerror(errno));
        plcrt_slave_free(s);
        return -1;
    }
    socklen_t len = sizeof addr;
    getsockname(s->listen_fd, (struct sockaddr *)&addr, &len);
    s->port = ntohs(addr.sin_port);
    rt->slave = s;
    plcrt_log(rt, "Modbus slave listening on %s:%d", host, s->port);
    if (rt->mode == PLCRT_REALTIME && rt->started) return plcrt_slave_start_thread(rt);
    return 0;
}

int plcrt_slave_port(const plcrt_t *rt) { return rt->slave ? rt->slave->port : 0; }

static void image_to_map(plcrt_t *rt, modbus_mapping_t *mp)
{
    memcpy(mp->tab_registers, rt->img.qw, sizeof rt->img.qw);
    memcpy(mp->tab_registers + PLCRT_IMAGE_SIZE, rt->img.mw, sizeof rt->img.mw);
    memcpy(mp->tab_input_registers, rt->img.iw, sizeof rt->img.iw);
    memcpy(mp->tab_bits, rt->img.qx, NBITS);
    memcpy(mp->tab_input_bits, rt->img.ix, NBITS);
}

static void map_to_image(plcrt_t *rt, modbus_mapping_t *mp)
{
    memcpy(rt->img.qw, mp->tab_registers, sizeof rt->img.qw);
    memcpy(rt->img.mw, mp->tab_registers + PLCRT_IMAGE_SIZE, sizeof rt->img.mw);
    for (int i = 0; i < NBITS; i++) (&rt->img.qx[0][0])[i] = mp->tab_bits[i] ? 1 : 0;
}

static void drop_client(struct plcrt_slave *s, int i)
{
    close(s->clients[i]);
    s->clients[i] = s->clients[--s->n_clients];
}

/* Accepts and serves what is ready within timeout_ms; lock: take rt->image_lock per reply. */
static int serve(plcrt_t *rt, int timeout_ms, int lock)
{
    struct plcrt_slave *s = rt->slave;
    if (!s) return 0;
    int served = 0;
    for (;;) {
        fd_set rd;
        FD_ZERO(&rd);
        FD_SET(s->listen_fd, &rd);
        int maxfd = s->listen_fd;
        for (int i = 0; i < s->n_clients; i++) {
            FD_SET(s->clients[i], &rd);
            if (s->clients[i] > maxfd) maxfd = s->clients[i];
        }
        struct timeval tv = {timeout_ms / 1000, (timeout_ms % 1000) * 1000};
        int n = select(maxfd + 1, &rd, NULL, NULL, &tv);
        if (n <= 0) return served;
        timeout_ms = 0; /* after the first wait, only what is ready now */
        if (FD_ISSET(s->listen_fd, &rd)) {
            int c = accept(s->listen_fd, NULL, NULL);
            if (c >= 0) {
                if (s->n_clients == MAX_CLIENTS) close(c);
                else s->clients[s->n_clients++] = c;
            }
        }
        for (int i = s->n_clients - 1; i >= 0; i--) {
            if (!FD_ISSET(s->clients[i], &rd)) continue;
            uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
            modbus_set_socket(s->ctx, s->clients[i]);
            int rc = modbus_receive(s->ctx, q);
            if (rc == 0) continue; /* not for us (other unit id): ignored */
            if (rc < 0) { drop_client(s, i); continue; }
            if (lock) pthread_mutex_lock(&rt->image_lock);
            image_to_map(rt, s->map);
            int ok = modbus_reply(s->ctx, q, rc, s->map) >= 0;
            map_to_image(rt, s->map);
            if (lock) pthread_mutex_unlock(&rt->image_lock);
            served++;
            if (!ok) drop_client(s, i);
        }
    }
}

int plcrt_slave_poll(plcrt_t *rt, int timeout_ms) { return serve(rt, timeout_ms, 1); }

static void *slave_thread(void *arg)
{
    plcrt_t *rt = arg;
    while (!rt->slave->stop) serve(rt, 100, 1);
    return NULL;
}

int plcrt_slave_start_thread(plcrt_t *rt)
{
    struct plcrt_slave *s = rt->slave;
    if (!s || s->thread_running) return 0;
    s->stop = 0;
    if (pthread_create(&s->thread, NULL, slave_thread, rt) != 0) {
        plcrt_seterr(rt, "cannot start the Modbus slave thread");
        return -1;
    }
    s->thread_running = 1;
    return 0;
}

void plcrt_slave_stop_thread(plcrt_t *rt)
{
    struct plcrt_slave *s = rt->slave;
    if (!s || !s->thread_running) return;
    s->stop = 1;
    pthread_join(s->thread, NULL);
    s->thread_running = 0;
}
