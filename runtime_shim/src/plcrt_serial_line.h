/* Internal: an RTU exchange's time on the wire in virtual time (plcrt_serial_line.c). */
#ifndef PLCRT_SERIAL_LINE_H
#define PLCRT_SERIAL_LINE_H

#include "plcrt_master.h"

/* the device's exchanges are modelled on its line (RTU, virtual time) */
int plcrt_line_modelled(plcrt_t *rt, const plcrt_device_t *d);

/* moves the exchange on the line of owner o on to now; returns 1 while the line is busy */
int plcrt_line_advance(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *o, uint64_t now);

/* puts request q of range r on the idle line of owner o (pair: the write range of an FC23
 * that goes with it, -1 = none); -1 when out of memory */
int plcrt_line_start(plcrt_t *rt, struct plcrt_master *m, plcrt_device_t *o, plcrt_range_t *r,
                     const request_t *q, uint64_t now, int pair);

#endif
