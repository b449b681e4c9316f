/* mipcosim: soft-PLCs (plcrt) and the emulated MIP radio network (mipemu) in one process,
 * in lockstep virtual time.
 *
 * The simulation owns a mipemu network. Each PLC is a plcrt instance from its own copy of a
 * program library; the simulation only holds function pointers into that copy (plcrt_scan,
 * plcrt_device_set_fd), so any number of programs can run side by side. A PLC's Modbus
 * device is wired to an emulator endpoint in process (mipcosim_connect_inproc: the runtime
 * hands each request ADU to the emulator core and parses the response ADU) or through a
 * socketpair (mipcosim_connect) - all in the calling thread, at the current virtual time.
 *
 * The run loop scans every PLC whose next tick is due and advances the radio to each tick,
 * so a run is a pure function of the configuration, the programs and the seed.
 * Functions returning int give 0 (or an id >= 0) on success and -1 on error
 * (mipcosim_errmsg). */
#ifndef MIPCOSIM_H
#define MIPCOSIM_H

#include <stddef.h>
#include <stdint.h>

#include "mipemu.h"  /* the library exports the core's API too (tests/st_lib uses it directly) */
#include "siprotec.h" /* and the SIPROTEC relay core's (issue 35: mipcosim_relay_add below) */

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mipcosim mipcosim;

/* int plcrt_scan(plcrt_t *rt, uint64_t n) and plcrt_device_set_fd of one library copy. */
typedef int (*mipcosim_scan_fn)(void *rt, uint64_t n);
typedef void (*mipcosim_after_send_fn)(void *user);
typedef int (*mipcosim_set_fd_fn)(void *rt, const char *device, int fd,
                                  mipcosim_after_send_fn after_send, void *user);

/* NULL if the network configuration is invalid (reason in err). */
mipcosim *mipcosim_new(const mipemu_config *cfg, char *err, size_t errlen);
/* The same with the config fields as arguments (for callers without the struct layout). */
mipcosim *mipcosim_new_args(int stations, int mode, int static_registers, double loss_down,
                            double loss_up, double burst, uint64_t seed, uint32_t bitrate,
                            uint64_t slot_gap_ns, int overhead_bytes, char *err, size_t errlen);
void mipcosim_free(mipcosim *sim);
const char *mipcosim_errmsg(const mipcosim *sim);
mipemu_net *mipcosim_net(mipcosim *sim);
uint64_t mipcosim_now(const mipcosim *sim);

/* Adds a PLC scanned every tick_ns from the current time on; returns its id. */
int mipcosim_plc_add(mipcosim *sim, mipcosim_scan_fn scan, void *rt, uint64_t tick_ns);
/* Replaces PLC id's instance (a restart), first scan at the current time. rt = NULL switches
 * the PLC off (not scanned, its modem keeps running) until the next replace. The taps of the
 * old instance are dropped (tap the new one again); its connections stay, like a PLC that
 * reconnects to its modem (half-exchanged bytes are dropped): connect the new instance again,
 * which hands it the same connection. */
int mipcosim_plc_replace(mipcosim *sim, int id, mipcosim_scan_fn scan, void *rt, uint64_t tick_ns);

/* Wires device `device` of PLC id to endpoint ep (0 = MDP, s = TRM of station s). */
int mipcosim_connect(mipcosim *sim, int id, mipcosim_set_fd_fn set_fd, const char *device, int ep);
/* The same over a real TCP connection on 127.0.0.1 (made in the calling thread): Modbus TCP
 * exactly as the runtime speaks it to a modem, still in lockstep (to compare transports). */
int mipcosim_connect_tcp(mipcosim *sim, int id, mipcosim_set_fd_fn set_fd, const char *device,
                         int ep);

/* The same without a socket (the kernel's default): the runtime's in-process transport
 * (plcrt_device_set_transport of that library copy) hands each request ADU to the emulator
 * core (mipemu_handle at the current virtual time) and parses the response ADU with the same
 * code as over TCP. */
typedef long (*mipcosim_transact_fn)(void *user, const uint8_t *req, size_t req_len,
                                     uint8_t *rsp, size_t rsp_cap);
typedef int (*mipcosim_set_transport_fn)(void *rt, const char *device,
                                         mipcosim_transact_fn transact, void *user);
int mipcosim_connect_inproc(mipcosim *sim, int id, mipcosim_set_transport_fn set_transport,
                            const char *device, int ep);

/* One Modbus request of a participant that is not a plcrt PLC (e.g. a peer written in Python
 * that the caller steps between runs, or a scan function of its own): the request ADU (MBAP
 * header + PDU, one whole frame, as sent over Modbus TCP) goes to endpoint ep (0 = MDP, s = TRM
 * of station s) of the emulator core at the current virtual time (mipemu_handle, as the
 * in-process transport does for a PLC) and the response ADU is written to rsp (rsp_cap >=
 * MIPEMU_RESPONSE_MAX). Returns its length, or -1 (mipcosim_errmsg): no such endpoint, not one
 * whole frame, or a frame the emulator would close the connection for (no answer). May be
 * called between runs or from a scan function during mipcosim_run. Counted in
 * mipcosim_requests. */
long mipcosim_request(mipcosim *sim, int ep, const uint8_t *req, size_t req_len, uint8_t *rsp,
                      size_t rsp_cap);

/* Taps: after every scan of PLC id, if the 16-bit word at seq changed, one entry is logged:
 * the nhdr words at hdr, then min(hdr[len_index], ndata_max) words at data (len_index < 0 or
 * data NULL: no data), then the new value of seq. tap is a slot number chosen by the caller (0..63); setting it again
 * rebinds it (e.g. after a restart) and takes the current seq as seen. */
int mipcosim_tap(mipcosim *sim, int tap, int id, const uint16_t *seq, const uint16_t *hdr,
                 int nhdr, int len_index, const uint16_t *data, int ndata_max);
/* The same with the header's words taken one by one from fields[0..nfields-1] (at most 16):
 * for a block instance whose outputs are not contiguous (the kit's delivery tap). */
int mipcosim_tap_fields(mipcosim *sim, int tap, int id, const uint16_t *seq,
                        const uint16_t *const *fields, int nfields, int len_index,
                        const uint16_t *data, int ndata_max);
void mipcosim_untap(mipcosim *sim, int tap);
/* Moves logged entries into buf: per entry [tap, plc id, nwords, words...]; returns the number
 * of words written (whole entries only). */
size_t mipcosim_tap_read(mipcosim *sim, uint16_t *buf, size_t cap);

/* Runs until virtual time until_ns (scans due at until_ns are not run). -1 when a scan failed
 * (mipcosim_failed_plc names the PLC; its plcrt_errmsg tells why). */
int mipcosim_run(mipcosim *sim, uint64_t until_ns);
int mipcosim_failed_plc(const mipcosim *sim);

/* Counters: Modbus requests answered by the emulator (either transport), scans run. */
uint64_t mipcosim_requests(const mipcosim *sim);
uint64_t mipcosim_scans(const mipcosim *sim);

/* Trace lines of the emulator go to path (NULL: off). */
int mipcosim_trace_file(mipcosim *sim, const char *path);

/* SIPROTEC relays (emulator/src/siprotec.c, docs/chain.md "The relay") in the same virtual
 * time: mipcosim_run lets each relay's event source run up to every time step, and a request
 * reaches the relay at the current virtual time. A relay is not a station of the radio
 * network: a PLC talks to it over its own Modbus device (the outstation's Modbus client to
 * the relay next to it). Returns the relay's id (0..), or -1 (mipcosim_errmsg: the
 * configuration's reason, or too many relays). The kernel frees it. */
int mipcosim_relay_add(mipcosim *sim, const siprotec_config *cfg);
/* Relay rid restarts (a power cycle): a new core from cfg takes its place at the current virtual
 * time, its recorder empty and its sequence number 0; PLCs connected to rid talk to the new one.
 * The old core's entries are gone (our choice: the recorder is not kept over a restart). */
int mipcosim_relay_restart(mipcosim *sim, int rid, const siprotec_config *cfg);
/* The relay's core for the siprotec_* API (scripted events, stats, peek); NULL: no such id. */
siprotec_relay *mipcosim_relay(mipcosim *sim, int rid);
/* PLC id's device (a Modbus TCP client of the runtime) talks to relay rid in process, as
 * mipcosim_connect_inproc does for a modem. */
int mipcosim_connect_relay(mipcosim *sim, int id, mipcosim_set_transport_fn set_transport,
                           const char *device, int rid);
/* One request of a participant that is not a plcrt PLC, to relay rid at the current virtual
 * time (as mipcosim_request for the modems). Returns the response's length, or -1. */
long mipcosim_relay_request(mipcosim *sim, int rid, const uint8_t *req, size_t req_len,
                            uint8_t *rsp, size_t rsp_cap);

#ifdef __cplusplus
}
#endif
#endif
