/* Modbus TCP master (placeholder until the master lands). */
#include "plcrt_internal.h"
#include <stdlib.h>

struct plcrt_master { int empty; };

int plcrt_master_parse(plcrt_t *rt, const char *name, const char *text, struct plcrt_master **out)
{
    (void)text; (void)out;
    plcrt_seterr(rt, "%s:1: error: the Modbus master is not implemented yet", name);
    return -1;
}
void plcrt_master_free(struct plcrt_master *m) { free(m); }
void plcrt_master_exchange_out(plcrt_t *rt, struct plcrt_master *m) { (void)rt; (void)m; }
void plcrt_master_exchange_in(plcrt_t *rt, struct plcrt_master *m) { (void)rt; (void)m; }
void plcrt_master_step(plcrt_t *rt, struct plcrt_master *m, uint64_t now_ns) { (void)rt; (void)m; (void)now_ns; }
int plcrt_master_start_thread(plcrt_t *rt, struct plcrt_master *m) { (void)rt; (void)m; return 0; }
void plcrt_master_stop_thread(struct plcrt_master *m) { (void)m; }
int plcrt_device_set_fd(plcrt_t *rt, const char *device, int fd, plcrt_after_send_fn f, void *u)
{ (void)device; (void)fd; (void)f; (void)u; plcrt_seterr(rt, "no such device"); return -1; }
int plcrt_device_count(const plcrt_t *rt) { (void)rt; return 0; }
const char *plcrt_device_name(const plcrt_t *rt, int i) { (void)rt; (void)i; return NULL; }
int plcrt_device_stats(const plcrt_t *rt, int i, uint64_t *e, uint64_t *r, uint64_t *c)
{ (void)rt; (void)i; (void)e; (void)r; (void)c; return -1; }
