/* A hand-written program with the matiec ABI, standing in for translator output in the
 * C unit tests: two tasks (every tick and every 5th tick), located I/O, a time log. */
#include <stddef.h>
#include <stdint.h>
#include <time.h>

extern uint16_t *__IW100, *__QW100;
extern uint8_t *__IX0_0, *__QX0_1;
extern uint32_t *__MD5;
extern struct { long tv_sec; long tv_nsec; } __CURRENT_TIME;

unsigned long long common_ticktime__ = 10000000ULL; /* 10 ms */

uint32_t fake_fast_count, fake_slow_count;
uint64_t fake_time_seen[64]; /* __CURRENT_TIME in ns as seen by the first 64 runs */
int16_t fake_counter;        /* a symbol for the accessor table */
long fake_sleep_ns;          /* > 0: every run takes at least this long (overrun tests) */
unsigned long fake_last_tick;

void config_init__(void)
{
    fake_fast_count = fake_slow_count = 0;
    fake_counter = 0;
    fake_sleep_ns = 0;
    *__QW100 = 0;
}

void config_run__(unsigned long tick)
{
    if (fake_fast_count < 64)
        fake_time_seen[fake_fast_count] =
            (uint64_t)__CURRENT_TIME.tv_sec * 1000000000ull + (uint64_t)__CURRENT_TIME.tv_nsec;
    fake_fast_count++;
    if (tick % 5 == 0) fake_slow_count++;
    fake_counter++;
    fake_last_tick = tick;
    if (fake_sleep_ns > 0) {
        struct timespec ts = {fake_sleep_ns / 1000000000L, fake_sleep_ns % 1000000000L};
        while (nanosleep(&ts, &ts) != 0) {
        }
    }
    *__QW100 = (uint16_t)(*__IW100 + 1);
    *__QX0_1 = *__IX0_0;
    *__MD5 = fake_fast_count;
}

/* what plcharness.build generates from SYMBOLS.tsv */
const char *const plcrt_gen_symbol_names[] = {"CONFIG0.RES0.INSTANCE0.COUNTER", 0};
const size_t plcrt_gen_n_symbols = 1;
void *plcrt_gen_symbol_addr(size_t i) { return i == 0 ? (void *)&fake_counter : NULL; }

/* what stc generates in RETAIN.c: the retained variables, addresses at run time */
const char *const plcrt_gen_retain_names[] = {"CONFIG0.RES0.INSTANCE0.COUNTER",
                                              "CONFIG0.RES0.INSTANCE0.FAST", 0};
const char *const plcrt_gen_retain_types[] = {"INT", "UDINT", 0};
const size_t plcrt_gen_n_retain = 2;
void *plcrt_gen_retain_addr(size_t i)
{
    return i == 0 ? (void *)&fake_counter : i == 1 ? (void *)&fake_fast_count : NULL;
}
size_t plcrt_gen_retain_size(size_t i)
{
    return i == 0 ? sizeof fake_counter : i == 1 ? sizeof fake_fast_count : 0;
}
