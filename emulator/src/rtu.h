/* Modbus RTU on a serial line for the mip-emulator server: framing (CRC-16, 3.5-character gap),
 * wire timing (character time from baud, data, parity and stop bits), unit id -> endpoint
 * routing, and the line itself (a pty the server creates, or a given tty). No radio, no core
 * state: the server hands every complete frame for an endpoint to mipemu_handle as a Modbus
 * TCP ADU and gets the answer back; this module only decides when and what goes on the line. */
#ifndef MIP_RTU_H
#define MIP_RTU_H

#include <stddef.h>
#include <stdint.h>

#define RTU_ADU_MAX 256     /* unit id + PDU (<= 253) + CRC */
#define RTU_MAX_DEVICES 16  /* devices on one bus */

typedef struct rtu_dev {
    int ep;       /* core endpoint: 0 = MDP-810 (unit id = station 1..N), s = TRM-810 of station s */
    int unit;     /* TRM: its unit id on the bus (1..247); MDP: 0 (the stations' unit ids) */
} rtu_dev;

typedef struct rtu_bus {
    /* configuration */
    char spec[512];         /* as given, for messages */
    char path[256];         /* tty path, or the pty's /dev/pts/N */
    char link[256];         /* pty: symlink created to it ("" = none) */
    int is_pty;
    long baud;
    int data_bits, stop_bits;
    char parity;            /* 'N', 'E', 'O' */
    rtu_dev dev[RTU_MAX_DEVICES];
    int n_dev;
    int stations;           /* stations of the network (MDP unit ids 1..stations) */
    /* line */
    int fd;                 /* pty master or the tty */
    int keep_fd;            /* pty: the server's own handle on the slave side (no EIO/HUP) */
    int watch_fd;           /* pty: inotify on the closes of the slave side (or -1) */
    /* receive */
    uint8_t rx[RTU_ADU_MAX * 2];
    size_t rx_len;
    int rx_overflow;        /* more than RTU_ADU_MAX bytes without a gap: not a frame */
    int rx_broken;          /* a silence over t1.5 inside the frame: discarded at its end */
    uint64_t rx_end_ns;     /* when the last character received has crossed the wire */
    /* the answer waiting for its time on the line */
    uint8_t tx[RTU_ADU_MAX];
    size_t tx_len;
    uint64_t tx_at_ns;
    /* counters */
    unsigned long frames, crc_errors, broken, foreign, broadcasts, answered;
} rtu_bus;

/* CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF); the frame carries it low byte first */
uint16_t rtu_crc16(const uint8_t *p, size_t n);

/* Parses "PORT[:BAUD[:FRAME]]=DEV[,DEV...]" into b; PORT is "pty", "pty:LINKPATH" or a tty path,
 * BAUD 300..4000000 (default 19200), FRAME like 8N1 / 8E1 / 7O2 (default 8N1), DEV "mdp" (unit
 * ids 1..stations) or "trmS@U" (the TRM-810 of station S at unit id U). 0 or -1 with a message. */
int rtu_parse(rtu_bus *b, const char *spec, int stations, char *err, size_t errn);

/* Opens the line (creates the pty and its link); 0 or -1 with a message. */
int rtu_open(rtu_bus *b, char *err, size_t errn);
void rtu_close(rtu_bus *b);

/* pty: keeps a client's parity setup from failing (see rtu.c): re-arms the slave side's
 * settings; rtu_on_watch when watch_fd is readable (a client closed the pty). */
void rtu_pty_rearm(rtu_bus *b);
void rtu_on_watch(rtu_bus *b);

/* pty: the line saying that a pty carries no parity (1), or nothing for a tty (0) */
int rtu_parity_note(const rtu_bus *b, char *out, size_t n);

/* Time on the wire of one character (start + data + parity + stop bits), of the silent
 * interval that ends a frame (t3.5: 3.5 characters, 1.75 ms above 19,200 baud) and of the
 * longest silence allowed inside a frame (t1.5: 1.5 characters, 750 us above 19,200 baud), as
 * the Modbus serial line specification V1.02, section 2.5.1.1, fixes them. */
uint64_t rtu_char_ns(const rtu_bus *b);
uint64_t rtu_gap_ns(const rtu_bus *b);
uint64_t rtu_t15_ns(const rtu_bus *b);

/* Handles what is due at now: a frame closed by the gap is checked (CRC, unit id) and
 * handed to handle(user, ep, tcp_adu, len, resp, cap) at the time it would have ended on the
 * wire (the caller advances the core to that time, *at_ns); a due answer is written.
 * Bad CRC, unknown unit ids, broadcasts (unit 0, handed to every device), frames with a silence
 * over t1.5 inside and requests the core drops are answered with silence, as a real RTU slave
 * does. */
typedef long (*rtu_handle_fn)(void *user, int ep, uint64_t at_ns, const uint8_t *req, size_t len,
                              uint8_t *resp, size_t cap);
void rtu_on_time(rtu_bus *b, uint64_t now, rtu_handle_fn handle, void *user);

/* The framing (t1.5, t3.5) as a function of bytes and times: n bytes a client wrote, arriving
 * at now (ns, any clock that never goes back). A frame whose t3.5 has passed at now is handled
 * first (rtu_on_time). The server calls it with what it reads and the monotonic clock; the
 * tests with explicit times. */
void rtu_feed(rtu_bus *b, const uint8_t *p, size_t n, uint64_t now, rtu_handle_fn handle, void *user);

/* The line is readable: reads the bytes and feeds them (now = when they were read). */
void rtu_on_readable(rtu_bus *b, uint64_t now, rtu_handle_fn handle, void *user);

/* Earliest time something is due (a frame to close, an answer to send); UINT64_MAX = none. */
uint64_t rtu_next_deadline(const rtu_bus *b);

#endif
