/* Modbus TCP slave (placeholder). */
#include "plcrt_internal.h"
void plcrt_slave_free(struct plcrt_slave *s) { (void)s; }
int plcrt_slave_start_thread(plcrt_t *rt) { (void)rt; return 0; }
void plcrt_slave_stop_thread(plcrt_t *rt) { (void)rt; }
int plcrt_slave_start(plcrt_t *rt, const char *host, int port)
{ (void)host; (void)port; plcrt_seterr(rt, "slave not implemented yet"); return -1; }
int plcrt_slave_port(const plcrt_t *rt) { (void)rt; return 0; }
int plcrt_slave_poll(plcrt_t *rt, int timeout_ms) { (void)rt; (void)timeout_ms; return 0; }
