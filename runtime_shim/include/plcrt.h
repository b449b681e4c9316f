/* plcrt: a small soft-PLC runtime for programs compiled by stc or matiec.
 *
 * One program is linked with the core per executable / shared library (the program's
 * state lives in C globals), so there is one plcrt_t per process image of a program.
 * Every function returning int returns 0 on success and -1 on error; the error text is
 * then available from plcrt_errmsg(). */
#ifndef PLCRT_H
#define PLCRT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define PLCRT_IMAGE_SIZE 1024 /* n < 1024 for %IW n, %QW n, %MW n, %MD n, %ML n, a in %IX a.b */

/* The located image, with OpenPLC's address space. */
typedef struct plcrt_image {
    uint8_t ix[PLCRT_IMAGE_SIZE][8]; /* %IX a.b, 0/1 */
    uint8_t qx[PLCRT_IMAGE_SIZE][8]; /* %QX a.b */
    uint8_t ib[PLCRT_IMAGE_SIZE];    /* %IB n */
    uint8_t qb[PLCRT_IMAGE_SIZE];    /* %QB n */
    uint16_t iw[PLCRT_IMAGE_SIZE];   /* %IW n */
    uint16_t qw[PLCRT_IMAGE_SIZE];   /* %QW n */
    uint16_t mw[PLCRT_IMAGE_SIZE];   /* %MW n */
    uint32_t md[PLCRT_IMAGE_SIZE];   /* %MD n */
    uint64_t ml[PLCRT_IMAGE_SIZE];   /* %ML n */
} plcrt_image_t;

/* Pointer to a located address: area 'I','Q','M'; size 'X','B','W','D','L';
 * parts = {n} or {a, b} for bits. NULL when the address is outside the image
 * (why goes into err when err != NULL). */
void *plcrt_image_locate(plcrt_image_t *img, char area, char size, const long *parts,
                         int nparts, char *err, size_t errlen);
/* Parse "%QW100" / "%IX0.1" (also without '%'); 0 or -1. */
int plcrt_parse_address(const char *text, char *area, char *size, long parts[2], int *nparts);

/* What a compiled program provides (filled by the generated glue, plcrt_abi.c). */
typedef struct plcrt_timespec { long tv_sec; long tv_nsec; } plcrt_timespec_t;
typedef struct plcrt_program {
    void (*init)(void);
    void (*run)(unsigned long tick);
    unsigned long long *ticktime_ns;
    plcrt_timespec_t *current_time;
    /* Points every located variable into img; -1 with a message naming the variable. */
    int (*bind)(plcrt_image_t *img, char *err, size_t errlen);
    size_t n_symbols;
    const char *const *symbol_names;       /* upper-case IEC paths */
    void *(*symbol_addr)(size_t i);        /* valid after init */
    /* Retained variables (RETAIN, and all of an FB instance declared RETAIN): path, type tag,
     * address (valid after init, computed at run time) and size in bytes. 0 when none. */
    size_t n_retain;
    const char *const *retain_names;
    const char *const *retain_types;
    void *(*retain_addr)(size_t i);
    size_t (*retain_size)(size_t i);
} plcrt_program_t;

/* The program linked into this executable / library (defined by the glue). */
const plcrt_program_t *plcrt_linked_program(void);

typedef struct plcrt plcrt_t;

typedef enum { PLCRT_VIRTUAL = 0, PLCRT_REALTIME = 1 } plcrt_mode_t;

/* Binds the located variables, runs config_init__. NULL on error (message in err). */
plcrt_t *plcrt_new(const plcrt_program_t *prog, char *err, size_t errlen);
void plcrt_free(plcrt_t *rt);
const char *plcrt_errmsg(const plcrt_t *rt);

plcrt_image_t *plcrt_image(plcrt_t *rt);
uint64_t plcrt_time_ns(const plcrt_t *rt);
uint64_t plcrt_tick_ns(const plcrt_t *rt);
uint64_t plcrt_scan_count(const plcrt_t *rt);

/* Loads a config file (own format or OpenPLC's mbconfig.cfg). Errors are one line
 * "FILE:LINE: error: ...". Must be called before the first scan. */
int plcrt_load_config(plcrt_t *rt, const char *path);
/* Like plcrt_load_config, from a string (name is used in messages). */
int plcrt_load_config_text(plcrt_t *rt, const char *name, const char *text);
/* Like plcrt_load_config, from len bytes: refused when larger than PLCRT_CONFIG_MAX or
 * when they contain a NUL byte. plcrt_load_config reads regular files only (directories,
 * devices, FIFOs are refused before reading) and at most PLCRT_CONFIG_MAX + 1 bytes. */
#define PLCRT_CONFIG_MAX (1 << 20)
int plcrt_load_config_mem(plcrt_t *rt, const char *name, const void *data, size_t len);

/* One scan in virtual time: I/O phase (Modbus in/out, handshakes) → forces → program
 * → forces → advance time by the tick. n scans. */
int plcrt_scan(plcrt_t *rt, uint64_t n);

typedef struct plcrt_rt_stats {
    uint64_t scans;
    uint64_t overruns;          /* scans that started after their deadline had passed */
    uint64_t max_late_ns;       /* worst start lateness */
    uint64_t max_scan_ns;       /* worst scan duration (I/O + program) */
} plcrt_rt_stats_t;

/* Real-time mode: absolute deadlines (CLOCK_MONOTONIC, clock_nanosleep), the Modbus
 * master in its own thread. Runs max_scans scans (0 = until *stop becomes non-zero). */
int plcrt_run_realtime(plcrt_t *rt, uint64_t max_scans, volatile int *stop);
void plcrt_rt_stats(const plcrt_t *rt, plcrt_rt_stats_t *out);

/* Writes the cycle / change write ranges now, with the outputs of the last scan, so that
 * the final state reaches the devices at the end of a run (plcrt_run_realtime does this
 * itself when it returns). */
int plcrt_flush_outputs(plcrt_t *rt);

/* Forces: the bytes are written to addr after the I/O phase and after the program,
 * every scan, until unforced. size <= 16. */
int plcrt_force(plcrt_t *rt, void *addr, const void *value, size_t size);
int plcrt_unforce(plcrt_t *rt, void *addr);

/* Symbols of the program by upper-case IEC path (NULL if unknown). */
size_t plcrt_symbol_count(const plcrt_t *rt);
const char *plcrt_symbol_name(const plcrt_t *rt, size_t i);
void *plcrt_symbol_addr(const plcrt_t *rt, size_t i);

/* ---- RETAIN (plcrt_retain.c) ----
 * A snapshot is: "PLCRTRT1", u32 version, u64 layout hash (FNV-1a over every retained
 * variable's path, type tag and size), u32 payload length, the payload (the retained
 * variables' bytes in table order), u32 CRC-32 of everything before it. Little-endian. */
size_t plcrt_retain_count(const plcrt_t *rt);
/* Size of a snapshot of this program's retained variables. */
size_t plcrt_retain_snapshot_size(const plcrt_t *rt);
/* Writes a snapshot into buf (cap bytes); its length, or 0 with plcrt_errmsg set. Call
 * between scans (the real-time loop and plcrt_retain_tick do). */
size_t plcrt_retain_save_to(plcrt_t *rt, void *buf, size_t cap);
/* Restores a snapshot: 0, or -1 with one line in plcrt_errmsg (truncated, bad checksum,
 * foreign file, other program layout); on -1 no variable has been touched. */
int plcrt_retain_load_from(plcrt_t *rt, const void *buf, size_t len);
/* File layer: writes PATH.tmp, fsync, rename over PATH, fsync of the directory, so PATH
 * always holds the last complete snapshot. 0 or -1. */
int plcrt_retain_save_file(plcrt_t *rt, const char *path);
/* 1 restored (warm), 0 nothing restored (no file: cold, silently; invalid file: cold, the
 * reason in plcrt_errmsg as one line). Never touches the variables unless it returns 1. */
int plcrt_retain_load_file(plcrt_t *rt, const char *path);
/* Saving to PATH: after a scan when period_ns of scan time (virtual or real) have passed
 * since the last snapshot, or when the config's [retain] request bit is TRUE after the scan
 * (at most one snapshot per scan), and by plcrt_retain_stop(). period_ns 0: on request and
 * on stop only. path NULL switches saving off. */
void plcrt_retain_set_file(plcrt_t *rt, const char *path, uint64_t period_ns);
/* The same saving (same decisions, same counter), but the snapshots go to a buffer in the
 * runtime instead of a file: the co-simulation's PLCs. Replaces a file set before. 0 or -1. */
int plcrt_retain_set_memory(plcrt_t *rt, uint64_t period_ns);
/* Copies the last complete in-memory snapshot into buf; its length, or 0 (none yet, buffer
 * too small: plcrt_errmsg). Restore it with plcrt_retain_load_from (a warm restart). */
size_t plcrt_retain_last(plcrt_t *rt, void *buf, size_t cap);
/* Saves now if a file or memory is set (the clean-stop save); 0 or -1. */
int plcrt_retain_stop(plcrt_t *rt);
/* Snapshots completed since plcrt_new (periodic, requested, on stop, plcrt_retain_save_file);
 * before every scan the runtime writes it, modulo 65536, into the config's [retain] saved
 * word. Failed saves do not count; they count in plcrt_retain_failures and are logged (the
 * first at once, then at most one line a minute of scan time). */
uint64_t plcrt_retain_saves(const plcrt_t *rt);
uint64_t plcrt_retain_failures(const plcrt_t *rt);
/* 1 when the config set [retain] request or saved (the durability handshake), else 0. */
int plcrt_retain_handshake(const plcrt_t *rt);
/* The file and period set by plcrt_retain_set_file or by a config's [retain] section
 * (file = PATH, period = 1s, request = %QXa.b, saved = %IWn); NULL when none. */
const char *plcrt_retain_file(const plcrt_t *rt);
uint64_t plcrt_retain_period_ns(const plcrt_t *rt);

/* Logging: lines go to the callback (default: stderr with a "plcrt: " prefix). */
typedef void (*plcrt_log_fn)(void *user, const char *line);
void plcrt_set_log(plcrt_t *rt, plcrt_log_fn fn, void *user);

/* ---- Modbus master (configured by plcrt_load_config) ---- */

/* Transport seam: instead of TCP, a device can talk over an fd (one end of a
 * socketpair()); after each request is sent, after_send(user) is called so a
 * single-threaded co-simulation can answer on the other end before the master
 * reads. Call before the first scan; the runtime does not close the fd. */
typedef void (*plcrt_after_send_fn)(void *user);
int plcrt_device_set_fd(plcrt_t *rt, const char *device, int fd,
                        plcrt_after_send_fn after_send, void *user);
/* In-process transport (the same seam, without a socket): every request ADU (MBAP header +
 * PDU, as it would go over TCP) is handed to transact(user, req, len, rsp, cap), which writes
 * the response ADU into rsp and returns its length, or -1 for no answer (seen as a timeout).
 * From the ADU on, the master runs the same code as over TCP. Call before the first scan. */
typedef long (*plcrt_transact_fn)(void *user, const uint8_t *req, size_t req_len, uint8_t *rsp,
                                  size_t rsp_cap);
int plcrt_device_set_transport(plcrt_t *rt, const char *device, plcrt_transact_fn transact,
                               void *user);
int plcrt_device_count(const plcrt_t *rt);
const char *plcrt_device_name(const plcrt_t *rt, int i);
/* Counters of a device: failed requests, successful requests, reconnects. */
int plcrt_device_stats(const plcrt_t *rt, int i, uint64_t *errors, uint64_t *requests,
                       uint64_t *connects);
/* Replies the master dropped because their transaction id was not the one of the request
 * (late or duplicated answers); logged the first time and every 100th. */
uint64_t plcrt_device_dropped_replies(const plcrt_t *rt, int i);

/* ---- Modbus slave (optional) ---- */
/* Serve the image (holding 0-1023 = %QW, 1024-2047 = %MW, input registers = %IW,
 * coils = %QX, discrete inputs = %IX) on host:port. port 0 picks a free port,
 * returned by plcrt_slave_port(). In virtual mode requests are served in the I/O
 * phase of each scan; in real-time mode by a thread. */
int plcrt_slave_start(plcrt_t *rt, const char *host, int port);
int plcrt_slave_port(const plcrt_t *rt);
/* Up to PLCRT_SLAVE_MAX_CLIENTS connections; a new one beyond replaces the connection
 * that has been quiet longest. A connection is closed after idle_ns without a byte
 * (no request under way) or byte_ns between two bytes of one request. */
#define PLCRT_SLAVE_MAX_CLIENTS 128
#define PLCRT_SLAVE_IDLE_TIMEOUT_NS 60000000000ull /* 60 s */
#define PLCRT_SLAVE_BYTE_TIMEOUT_NS 1000000000ull  /* 1 s */
int plcrt_slave_set_timeouts(plcrt_t *rt, uint64_t idle_ns, uint64_t byte_ns);
typedef struct plcrt_slave_stats {
    uint64_t clients;    /* connections open now */
    uint64_t accepted;   /* connections accepted */
    uint64_t requests;   /* requests answered (exceptions included) */
    uint64_t exceptions; /* answered with a Modbus exception */
    uint64_t closed;     /* closed by the client */
    uint64_t timeouts;   /* closed by the idle or inter-byte timeout */
    uint64_t bad_frames; /* closed: MBAP header not Modbus TCP (protocol id, length) */
    uint64_t evicted;    /* closed to make room for a new connection */
} plcrt_slave_stats_t;
int plcrt_slave_stats(const plcrt_t *rt, plcrt_slave_stats_t *out);
/* Serves an already connected stream socket (made non-blocking) as one more client, e.g.
 * one end of a socketpair(); the slave closes it. Virtual mode only (tests, fuzzing). */
int plcrt_slave_add_client(plcrt_t *rt, int fd);
/* Serves pending slave requests now (virtual mode; called by plcrt_scan too). */
int plcrt_slave_poll(plcrt_t *rt, int timeout_ms);

#ifdef __cplusplus
}
#endif
#endif
