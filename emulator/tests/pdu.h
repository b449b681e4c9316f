/* Modbus PDUs of the emulator's unit tests (test_mipemu.c, test_siprotec.c): the reply to a read
 * and the request of a write of registers, the same for the modem and the relay. */
#ifndef EMU_TEST_PDU_H
#define EMU_TEST_PDU_H

#include <stddef.h>
#include <stdint.h>

/* The reply resp (rlen bytes, the MBAP header first) to a read of q registers: its exception
 * code, or 0 with the values in vals (NULL: not kept), or -2 when its length is wrong. */
static inline int pdu_read_reply(const uint8_t *resp, long rlen, unsigned q, uint16_t *vals)
{
    if (resp[7] & 0x80)
        return resp[8];
    if (resp[8] != 2 * q || rlen != 9 + 2 * (long)q)
        return -2;
    for (unsigned i = 0; vals && i < q; i++)
        vals[i] = (uint16_t)(resp[9 + 2 * i] << 8 | resp[10 + 2 * i]);
    return 0;
}

/* The PDU of a write of q registers from address a (FC16) into p (6 + 2 * q bytes); returns
 * its length. */
static inline size_t pdu_write_regs(uint8_t *p, unsigned a, unsigned q, const uint16_t *vals)
{
    p[0] = 16; p[1] = (uint8_t)(a >> 8); p[2] = (uint8_t)a; p[3] = (uint8_t)(q >> 8); p[4] = (uint8_t)q;
    p[5] = (uint8_t)(2 * q);
    for (unsigned i = 0; i < q; i++) { p[6 + 2 * i] = (uint8_t)(vals[i] >> 8); p[7 + 2 * i] = (uint8_t)vals[i]; }
    return 6 + 2 * (size_t)q;
}

#endif
