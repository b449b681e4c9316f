/* Per-program glue, compiled once for every program with -I <translator output dir>
 * -I <generated dir>: defines what the matiec ABI asks of a runtime (__CURRENT_TIME,
 * __DEBUG, one pointer per located variable) and describes the program to the core. */
#include "plcrt.h"

#include <stdio.h>
#include <string.h>

extern void config_init__(void);
extern void config_run__(unsigned long tick);
extern unsigned long long common_ticktime__;

/* Layout-compatible with matiec's IEC_TIMESPEC / BOOL. */
plcrt_timespec_t __CURRENT_TIME;
uint8_t __DEBUG;

/* C storage of the elementary types a located variable can have. */
#define PLCRT_CT_BOOL uint8_t
#define PLCRT_CT_BYTE uint8_t
#define PLCRT_CT_SINT int8_t
#define PLCRT_CT_USINT uint8_t
#define PLCRT_CT_WORD uint16_t
#define PLCRT_CT_INT int16_t
#define PLCRT_CT_UINT uint16_t
#define PLCRT_CT_DWORD uint32_t
#define PLCRT_CT_DINT int32_t
#define PLCRT_CT_UDINT uint32_t
#define PLCRT_CT_REAL float
#define PLCRT_CT_LWORD uint64_t
#define PLCRT_CT_LINT int64_t
#define PLCRT_CT_ULINT uint64_t
#define PLCRT_CT_LREAL double

#define __LOCATED_VAR(type, name, area, size, ...) PLCRT_CT_##type *name;
#include "LOCATED_VARIABLES.h"
#undef __LOCATED_VAR

static size_t size_bytes(char size)
{
    switch (size) {
    case 'X': case 'B': return 1;
    case 'W': return 2;
    case 'D': return 4;
    default: return 8;
    }
}

/* One row per located variable, bound in a loop: a central's program has nearly 2000, and
 * one block of code per variable took gcc -O2 several seconds to compile (7.7 s for the
 * bidirectional central), a table takes none. */
typedef struct {
    void *var;            /* the pointer variable named like the address (__IW3) */
    const char *name, *type, *area, *size;
    size_t type_bytes;    /* sizeof the C storage of type */
    const long *parts;    /* the address's numbers, 3 for %IW3, 0 and 1 for %IX0.1 */
    int nparts;
} located_t;

#define __LOCATED_VAR(type, name, area, size, ...)                                          \
    {&name, #name, #type, #area, #size, sizeof(PLCRT_CT_##type), (const long[]){__VA_ARGS__}, \
     (int)(sizeof((const long[]){__VA_ARGS__}) / sizeof(long))},
static const located_t located[] = {
#include "LOCATED_VARIABLES.h"
    {0, 0, 0, 0, 0, 0, 0, 0} /* a program without located variables: an array still needs one */
};
#undef __LOCATED_VAR

static int bind_located(plcrt_image_t *img, char *err, size_t errlen)
{
    char why[200];
    for (size_t i = 0; i + 1 < sizeof located / sizeof located[0]; i++) {
        const located_t *l = &located[i];
        void *p = plcrt_image_locate(img, l->area[0], l->size[0], l->parts, l->nparts, why,
                                     sizeof why);
        if (!p) {
            snprintf(err, errlen, "located variable %s: %s", l->name, why);
            return -1;
        }
        if (l->type_bytes != size_bytes(l->size[0])) {
            snprintf(err, errlen, "located variable %s: type %s does not fit size %s", l->name,
                     l->type, l->size);
            return -1;
        }
        /* every PLCRT_CT_ pointer has the representation of a void * (POSIX) */
        memcpy(l->var, &p, sizeof p);
    }
    return 0;
}

/* From the generated plcrt_symbols.c; weak, so that a program linked by hand without a
 * symbol table still runs (with no symbols). */
extern const char *const plcrt_gen_symbol_names[] __attribute__((weak));
extern const size_t plcrt_gen_n_symbols __attribute__((weak));
extern void *plcrt_gen_symbol_addr(size_t i) __attribute__((weak));

/* From the generated RETAIN.c (stc); weak: a program without one retains nothing. */
extern const char *const plcrt_gen_retain_names[] __attribute__((weak));
extern const char *const plcrt_gen_retain_types[] __attribute__((weak));
extern const size_t plcrt_gen_n_retain __attribute__((weak));
extern void *plcrt_gen_retain_addr(size_t i) __attribute__((weak));
extern size_t plcrt_gen_retain_size(size_t i) __attribute__((weak));

static const plcrt_program_t program = {
    .init = config_init__,
    .run = config_run__,
    .ticktime_ns = &common_ticktime__,
    .current_time = &__CURRENT_TIME,
    .bind = bind_located,
    .n_symbols = 0, /* set below: a const object cannot take another object's value */
    .symbol_names = plcrt_gen_symbol_names,
    .symbol_addr = plcrt_gen_symbol_addr,
    .retain_names = plcrt_gen_retain_names,
    .retain_types = plcrt_gen_retain_types,
    .retain_addr = plcrt_gen_retain_addr,
    .retain_size = plcrt_gen_retain_size,
};

const plcrt_program_t *plcrt_linked_program(void)
{
    static plcrt_program_t p;
    p = program;
    p.n_symbols = &plcrt_gen_n_symbols && plcrt_gen_symbol_addr ? plcrt_gen_n_symbols : 0;
    p.n_retain = &plcrt_gen_n_retain && plcrt_gen_retain_addr && plcrt_gen_retain_size
                     ? plcrt_gen_n_retain : 0;
    return &p;
}
