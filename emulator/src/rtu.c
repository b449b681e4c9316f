/* Modbus RTU on a serial line for the mip-emulator server (see rtu.h). */
#define _GNU_SOURCE
#include "rtu.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/inotify.h>
#include <termios.h>
#include <unistd.h>

uint16_t rtu_crc16(const uint8_t *p, size_t n)
{
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc & 1) ? (uint16_t)((crc >> 1) ^ 0xA001) : (uint16_t)(crc >> 1);
    }
    return crc;
}

uint64_t rtu_char_ns(const rtu_bus *b)
{
    int bits = 1 + b->data_bits + (b->parity != 'N') + b->stop_bits;
    return (uint64_t)bits * 1000000000ull / (uint64_t)b->baud;
}

/* MODBUS over Serial Line Specification and Implementation Guide V1.02 (Modbus-IDA, 2006),
 * section 2.5.1.1 "MODBUS Message RTU Framing": frames are separated by a silent interval of at
 * least 3.5 character times (t3.5); a silent interval of more than 1.5 character times (t1.5)
 * between two characters makes the frame incomplete, to be discarded; above 19,200 baud the
 * recommended fixed values are t1.5 = 750 us and t3.5 = 1.750 ms. */
uint64_t rtu_gap_ns(const rtu_bus *b)
{
    if (b->baud > 19200) return 1750000ull;
    return rtu_char_ns(b) * 7 / 2;
}

uint64_t rtu_t15_ns(const rtu_bus *b)
{
    if (b->baud > 19200) return 750000ull;
    return rtu_char_ns(b) * 3 / 2;
}

static int fail(char *err, size_t n, const char *fmt, const char *a, const char *b2)
{
    snprintf(err, n, fmt, a, b2);
    return -1;
}

int rtu_parse(rtu_bus *b, const char *spec, int stations, char *err, size_t errn)
{
    memset(b, 0, sizeof *b);
    b->fd = b->keep_fd = b->watch_fd = -1;
    b->baud = 19200;
    b->data_bits = 8;
    b->parity = 'N';
    b->stop_bits = 1;
    b->stations = stations;
    snprintf(b->spec, sizeof b->spec, "%s", spec);
    char s[512];
    if (strlen(spec) >= sizeof s) return fail(err, errn, "--rtu '%s': too long%s", spec, "");
    strcpy(s, spec);
    char *eq = strrchr(s, '=');
    if (!eq) return fail(err, errn, "--rtu '%s': expected PORT[:BAUD[:FRAME]]=DEVICES, e.g. pty:19200:8E1=trm1@1%s", spec, "");
    *eq = 0;
    char *devs = eq + 1;
    /* PORT[:BAUD[:FRAME]], taken apart from the right, so that a path may hold ':' */
    const char *frame = NULL, *baud = NULL;
    char *c = strrchr(s, ':');
    if (c && strlen(c + 1) == 3 && c[1] >= '0' && c[1] <= '9' && !(c[2] >= '0' && c[2] <= '9')) {
        frame = c + 1; /* looks like a frame (8E1): checked below */
        *c = 0;
        c = strrchr(s, ':');
    }
    if (c && c[1] && strspn(c + 1, "0123456789") == strlen(c + 1)) {
        baud = c + 1;
        *c = 0;
    }
    if (!strcmp(s, "pty")) {
        b->is_pty = 1;
    } else if (!strncmp(s, "pty:", 4)) {
        b->is_pty = 1;
        if (!s[4]) return fail(err, errn, "--rtu '%s': pty: with an empty link%s", spec, "");
        if (strlen(s + 4) >= sizeof b->link) return fail(err, errn, "--rtu '%s': link path too long%s", spec, "");
        snprintf(b->link, sizeof b->link, "%s", s + 4);
    } else {
        if (!*s) return fail(err, errn, "--rtu '%s': no port%s", spec, "");
        if (strlen(s) >= sizeof b->path) return fail(err, errn, "--rtu '%s': path too long%s", spec, "");
        snprintf(b->path, sizeof b->path, "%s", s);
    }
    if (baud) {
        char *end;
        long v = strtol(baud, &end, 10);
        if (*end || v < 300 || v > 4000000)
            return fail(err, errn, "--rtu '%s': baud rate '%s' outside 300..4000000", spec, baud);
        b->baud = v;
    }
    if (frame) {
        const char *f = frame;
        if ((f[0] != '7' && f[0] != '8') || !strchr("NEO", f[1]) || (f[2] != '1' && f[2] != '2'))
            return fail(err, errn, "--rtu '%s': frame '%s' is not like 8N1, 8E1, 8O1, 8N2", spec, f);
        b->data_bits = f[0] - '0';
        b->parity = f[1];
        b->stop_bits = f[2] - '0';
    }
    /* devices */
    char *save = NULL;
    for (char *d = strtok_r(devs, ",", &save); d; d = strtok_r(NULL, ",", &save)) {
        if (b->n_dev == RTU_MAX_DEVICES) return fail(err, errn, "--rtu '%s': more than 16 devices on one bus%s", spec, "");
        rtu_dev *x = &b->dev[b->n_dev];
        int st, unit;
        char tail;
        if (!strcmp(d, "mdp")) {
            x->ep = 0;
            x->unit = 0;
        } else if (sscanf(d, "trm%d@%d%c", &st, &unit, &tail) == 2) {
            if (st < 1 || st > stations)
                return fail(err, errn, "--rtu '%s': '%s': no such station", spec, d);
            if (unit < 1 || unit > 247)
                return fail(err, errn, "--rtu '%s': '%s': unit id outside 1..247", spec, d);
            x->ep = st;
            x->unit = unit;
        } else {
            return fail(err, errn, "--rtu '%s': device '%s' is not 'mdp' or 'trmS@UNIT'", spec, d);
        }
        b->n_dev++;
    }
    if (!b->n_dev) return fail(err, errn, "--rtu '%s': no device on the bus%s", spec, "");
    /* every unit id answers for one device only */
    for (int i = 0; i < b->n_dev; i++)
        for (int j = 0; j < b->n_dev; j++) {
            if (i == j) continue;
            const rtu_dev *p = &b->dev[i], *q = &b->dev[j];
            int clash = (p->ep == 0 && q->ep == 0) || (p->ep && q->ep && p->unit == q->unit) ||
                        (p->ep == 0 && q->ep && q->unit <= stations);
            if (clash) return fail(err, errn, "--rtu '%s': two devices answer the same unit id%s", spec, "");
        }
    return 0;
}

static void set_line(struct termios *t, const rtu_bus *b)
{
    cfmakeraw(t);
    static const struct { long baud; speed_t s; } speeds[] = {
        {300, B300}, {600, B600}, {1200, B1200}, {2400, B2400}, {4800, B4800}, {9600, B9600},
        {19200, B19200}, {38400, B38400}, {57600, B57600}, {115200, B115200}, {230400, B230400},
        {460800, B460800}, {921600, B921600}, {1000000, B1000000}, {2000000, B2000000},
        {4000000, B4000000}};
    speed_t sp = B19200;
    for (size_t i = 0; i < sizeof speeds / sizeof speeds[0]; i++)
        if (speeds[i].baud == b->baud) sp = speeds[i].s;
    cfsetispeed(t, sp);
    cfsetospeed(t, sp);
    t->c_cflag &= (tcflag_t)~(CSIZE | PARENB | PARODD | CSTOPB);
    t->c_cflag |= (b->data_bits == 7 ? CS7 : CS8) | CLOCAL | CREAD;
    /* with parity, the UART checks it: a character with a parity error is read as \0 (INPCK
     * without IGNPAR or PARMRK, termios(3)), so its frame fails the CRC and is discarded */
    t->c_iflag &= (tcflag_t)~(INPCK | IGNPAR | PARMRK);
    if (b->parity != 'N') t->c_cflag |= PARENB, t->c_iflag |= INPCK;
    if (b->parity == 'O') t->c_cflag |= PARODD;
    if (b->stop_bits == 2) t->c_cflag |= CSTOPB;
    t->c_cc[VMIN] = 0;
    t->c_cc[VTIME] = 0;
}

int rtu_open(rtu_bus *b, char *err, size_t errn)
{
    struct termios t;
    if (b->is_pty) {
        int fd = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0 || grantpt(fd) < 0 || unlockpt(fd) < 0 || !ptsname(fd)) {
            snprintf(err, errn, "--rtu '%s': cannot create a pty: %s", b->spec, strerror(errno));
            return -1;
        }
        snprintf(b->path, sizeof b->path, "%s", ptsname(fd));
        /* keep the slave side open ourselves: else the master reads EIO / HUP while no client has it */
        int keep = open(b->path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
        if (keep < 0) {
            snprintf(err, errn, "--rtu '%s': cannot open %s: %s", b->spec, b->path, strerror(errno));
            close(fd);
            return -1;
        }
        if (tcgetattr(keep, &t) == 0) {
            set_line(&t, b); /* raw: no echo, no line editing on the client's side */
            tcsetattr(keep, TCSANOW, &t);
        }
        b->fd = fd;
        b->keep_fd = keep;
        rtu_pty_rearm(b);
        /* a client closing the slave side: re-armed after it (rtu_pty_rearm; not at an open, which
         * would race with the client's own setup) */
        b->watch_fd = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
        if (b->watch_fd >= 0 && inotify_add_watch(b->watch_fd, b->path, IN_CLOSE) < 0) {
            close(b->watch_fd);
            b->watch_fd = -1;
        }
        if (b->link[0]) {
            unlink(b->link); /* a stale link of an earlier run */
            if (symlink(b->path, b->link) < 0) {
                snprintf(err, errn, "--rtu '%s': cannot create the link %s: %s", b->spec, b->link, strerror(errno));
                rtu_close(b);
                return -1;
            }
        }
        return 0;
    }
    int fd = open(b->path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        snprintf(err, errn, "--rtu '%s': cannot open %s: %s", b->spec, b->path, strerror(errno));
        return -1;
    }
    if (tcgetattr(fd, &t) < 0) {
        snprintf(err, errn, "--rtu '%s': %s is not a serial line: %s", b->spec, b->path, strerror(errno));
        close(fd);
        return -1;
    }
    set_line(&t, b);
    if (tcsetattr(fd, TCSANOW, &t) < 0) {
        snprintf(err, errn, "--rtu '%s': cannot set up %s: %s", b->spec, b->path, strerror(errno));
        close(fd);
        return -1;
    }
    tcflush(fd, TCIOFLUSH);
    b->fd = fd;
    return 0;
}

void rtu_close(rtu_bus *b)
{
    if (b->link[0]) unlink(b->link);
    if (b->fd >= 0) close(b->fd);
    if (b->keep_fd >= 0) close(b->keep_fd);
    if (b->watch_fd >= 0) close(b->watch_fd);
    b->fd = b->keep_fd = b->watch_fd = -1;
}

/* A pty carries no parity: Linux's pty driver clears PARENB (and sets CS8) on every tcsetattr
 * of the slave side, and glibc's tcsetattr (Debian 12's 2.36) reads the settings back and fails
 * with EINVAL when none of the flags changed but PARENB is not as asked. A client asking for
 * 8E1 thus fails whenever the pty already has the rest of its settings: on its second open (the
 * slave side, which the server keeps open, keeps the last client's settings). IGNBRK means
 * nothing on a pty (no break condition crosses it) and every raw setup clears it (cfmakeraw,
 * pyserial, libmodbus): set again after every client, it makes each client's first setup a
 * change. */
void rtu_pty_rearm(rtu_bus *b)
{
    struct termios t;
    if (!b->is_pty || b->keep_fd < 0 || tcgetattr(b->keep_fd, &t) < 0 || (t.c_iflag & IGNBRK)) return;
    t.c_iflag |= IGNBRK;
    tcsetattr(b->keep_fd, TCSANOW, &t);
}

void rtu_on_watch(rtu_bus *b)
{
    char buf[1024];
    while (b->watch_fd >= 0 && read(b->watch_fd, buf, sizeof buf) > 0) {
    }
    rtu_pty_rearm(b);
}

int rtu_parity_note(const rtu_bus *b, char *out, size_t n)
{
    if (!b->is_pty) return 0;
    const char *what = b->parity == 'E' ? " (even parity)" : b->parity == 'O' ? " (odd parity)" : "";
    snprintf(out, n, "%s is a pty: it carries no parity bit, so parity is not checked and a client's "
             "parity setting does not matter there; characters are timed as %d%c%d%s, %d bits",
             b->path, b->data_bits, b->parity, b->stop_bits, what,
             1 + b->data_bits + (b->parity != 'N') + b->stop_bits);
    return 1;
}

/* The receiver's framing is a function of the bytes and of the times they arrived, and of
 * nothing else (no clock here): the server passes the monotonic clock, the tests explicit
 * times. A pty delivers what a client wrote at once, so the line is modelled: the characters a
 * client wrote at t go on the wire at t, or when the ones before them have crossed it, one
 * character time each. The silence before them is the time from the end of the last character
 * to t; over t1.5 it breaks the frame, and a frame ends t3.5 after its last character. */
void rtu_feed(rtu_bus *b, const uint8_t *p, size_t n, uint64_t now, rtu_handle_fn handle, void *user)
{
    if (!n) return;
    rtu_on_time(b, now, handle, user); /* a frame whose t3.5 has passed ends before these bytes */
    uint64_t start = now;
    if (b->rx_len || b->rx_overflow) {
        if (now > b->rx_end_ns && now - b->rx_end_ns > rtu_t15_ns(b)) b->rx_broken = 1;
        if (b->rx_end_ns > start) start = b->rx_end_ns;
    }
    b->rx_end_ns = start + (uint64_t)n * rtu_char_ns(b);
    size_t room = sizeof b->rx - b->rx_len;
    size_t k = n < room ? n : room;
    memcpy(b->rx + b->rx_len, p, k);
    b->rx_len += k;
    if (n > k || b->rx_len > RTU_ADU_MAX) b->rx_overflow = 1;
}

void rtu_on_readable(rtu_bus *b, uint64_t now, rtu_handle_fn handle, void *user)
{
    uint8_t buf[512];
    for (;;) {
        ssize_t n = read(b->fd, buf, sizeof buf);
        if (n <= 0) {
            if (n < 0 && errno == EINTR) continue;
            rtu_pty_rearm(b); /* a client is there: its setup is done */
            return;
        }
        rtu_feed(b, buf, (size_t)n, now, handle, user);
    }
}

/* when the frame in rx ends: t3.5 after its last character crossed the wire */
static uint64_t frame_close_ns(const rtu_bus *b)
{
    return b->rx_end_ns + rtu_gap_ns(b);
}

uint64_t rtu_next_deadline(const rtu_bus *b)
{
    uint64_t t = UINT64_MAX;
    if (b->rx_len || b->rx_overflow) t = frame_close_ns(b);
    if (b->tx_len && b->tx_at_ns < t) t = b->tx_at_ns;
    return t;
}

/* one complete frame (unit id + PDU + CRC) */
static void handle_frame(rtu_bus *b, uint64_t at, rtu_handle_fn handle, void *user)
{
    size_t n = b->rx_len;
    b->frames++;
    if (n < 4 || rtu_crc16(b->rx, n - 2) != (uint16_t)(b->rx[n - 2] | (b->rx[n - 1] << 8))) {
        b->crc_errors++;
        return;
    }
    int unit = b->rx[0];
    uint8_t adu[6 + RTU_ADU_MAX];
    size_t pdu = n - 3; /* without unit id and CRC */
    adu[0] = adu[1] = 0;
    adu[2] = adu[3] = 0;
    adu[4] = (uint8_t)((pdu + 1) >> 8);
    adu[5] = (uint8_t)(pdu + 1);
    memcpy(adu + 6, b->rx, n - 2);
    uint8_t resp[512];
    if (unit == 0) {
        /* broadcast: every device on the bus takes it, none answers */
        b->broadcasts++;
        for (int i = 0; i < b->n_dev; i++)
            if (b->dev[i].ep) handle(user, b->dev[i].ep, at, adu, 6 + n - 2, resp, sizeof resp);
        return;
    }
    int ep = -1;
    for (int i = 0; i < b->n_dev && ep < 0; i++) {
        const rtu_dev *d = &b->dev[i];
        if (d->ep == 0 && unit >= 1 && unit <= b->stations) ep = 0;
        else if (d->ep && d->unit == unit) ep = d->ep;
    }
    if (ep < 0) {
        b->foreign++; /* another slave's unit id (or none's): not ours to answer */
        return;
    }
    long rl = handle(user, ep, at, adu, 6 + n - 2, resp, sizeof resp);
    if (rl < 8 || (size_t)rl - 6 + 2 > sizeof b->tx) return; /* the core dropped it: silence */
    size_t m = (size_t)rl - 6; /* unit id + PDU */
    memcpy(b->tx, resp + 6, m);
    uint16_t crc = rtu_crc16(b->tx, m);
    b->tx[m] = (uint8_t)crc;
    b->tx[m + 1] = (uint8_t)(crc >> 8);
    b->tx_len = m + 2;
    /* the answer starts one gap after the request ended on the wire; written whole when its last
     * character would have arrived */
    b->tx_at_ns = at + rtu_gap_ns(b) + (uint64_t)b->tx_len * rtu_char_ns(b);
    b->answered++;
}

static void close_frame(rtu_bus *b, rtu_handle_fn handle, void *user)
{
    if (b->rx_overflow) {
        b->frames++;
        b->crc_errors++;
    } else if (b->rx_broken) {
        b->frames++;
        b->broken++; /* a silence over t1.5 inside: incomplete, discarded */
    } else {
        handle_frame(b, b->rx_end_ns, handle, user); /* at the end of the request on the wire */
    }
    b->rx_len = 0;
    b->rx_overflow = 0;
    b->rx_broken = 0;
}

static void send_answer(rtu_bus *b)
{
    size_t off = 0;
    while (off < b->tx_len) {
        ssize_t k = write(b->fd, b->tx + off, b->tx_len - off);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) break; /* nobody reads the line: the answer is lost, as on a wire */
        off += (size_t)k;
    }
    b->tx_len = 0;
}

void rtu_on_time(rtu_bus *b, uint64_t now, rtu_handle_fn handle, void *user)
{
    /* what is due, in the order of its time */
    for (;;) {
        uint64_t close_at = (b->rx_len || b->rx_overflow) ? frame_close_ns(b) : UINT64_MAX;
        uint64_t send_at = b->tx_len ? b->tx_at_ns : UINT64_MAX;
        if (send_at <= now && send_at <= close_at)
            send_answer(b);
        else if (close_at <= now)
            close_frame(b, handle, user);
        else
            return;
    }
}
