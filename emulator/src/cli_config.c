/* Network options shared by the emulator's fronts; see cli_config.h. */
#include "cli_config.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *cli_prog = "mipemu";

void cli_usage_error(const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "%s: error: ", cli_prog);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, " (see --help)\n");
    exit(2);
}

long cli_long(const char *opt, const char *s, long lo, long hi)
{
    char *e;
    errno = 0;
    long v = strtol(s, &e, 10);
    if (errno || e == s || *e || v < lo || v > hi)
        cli_usage_error("%s expects an integer %ld..%ld, got '%s'", opt, lo, hi, s);
    return v;
}

double cli_double(const char *opt, const char *s, double lo, double hi)
{
    char *e;
    errno = 0;
    double v = strtod(s, &e);
    if (errno || e == s || *e || !(v >= lo && v <= hi))
        cli_usage_error("%s expects a number %g..%g, got '%s'", opt, lo, hi, s);
    return v;
}

enum { N_STATIONS, N_MODE, N_STATIC, N_LDOWN, N_LUP, N_BURST, N_SEED, N_BITRATE, N_GAP,
       N_OVERHEAD, N_FAILS, N_127, N_LOSE_RECORD };

const cli_net_option cli_net_options[] = {
    [N_STATIONS] = { "stations", 1 },       [N_MODE] = { "mode", 1 },
    [N_STATIC] = { "static-registers", 1 }, [N_LDOWN] = { "loss-down", 1 },
    [N_LUP] = { "loss-up", 1 },             [N_BURST] = { "burst", 1 },
    [N_SEED] = { "seed", 1 },               [N_BITRATE] = { "bitrate", 1 },
    [N_GAP] = { "slot-gap-ms", 1 },         [N_OVERHEAD] = { "overhead-bytes", 1 },
    [N_FAILS] = { "fail-polls", 1 },        [N_127] = { "allow-127", 0 },
    [N_LOSE_RECORD] = { "lose-record", 1 },
};
const int cli_net_option_count = (int)(sizeof cli_net_options / sizeof cli_net_options[0]);

int cli_net_option_find(const char *name)
{
    for (int i = 0; i < cli_net_option_count; i++)
        if (!strcmp(name, cli_net_options[i].name))
            return i;
    return -1;
}

void cli_net_option_apply(mipemu_config *c, int index, const char *v)
{
    char opt[40];
    snprintf(opt, sizeof opt, "--%s", cli_net_options[index].name);
    switch (index) {
    case N_STATIONS: c->stations = (int)cli_long(opt, v, 1, MIPEMU_MAX_STATIONS); break;
    case N_MODE:
        if (!strcmp(v, "dynamic")) c->mode = MIPEMU_DYNAMIC;
        else if (!strcmp(v, "static")) c->mode = MIPEMU_STATIC;
        else cli_usage_error("%s expects static or dynamic, got '%s'", opt, v);
        break;
    case N_STATIC: c->static_registers = (int)cli_long(opt, v, 1, MIPEMU_AREA_REGS); break;
    case N_LDOWN: c->loss_down = cli_double(opt, v, 0, 1); break;
    case N_LUP: c->loss_up = cli_double(opt, v, 0, 1); break;
    case N_BURST:
        c->burst = cli_double(opt, v, 0, 1e6);
        if (c->burst != 0 && c->burst < 1)
            cli_usage_error("%s expects 0 or a mean burst length >= 1, got '%s'", opt, v);
        break;
    case N_SEED: {
        char *e;
        errno = 0;
        unsigned long long s = strtoull(v, &e, 0);
        if (errno || e == v || *e || v[0] == '-')
            cli_usage_error("%s expects an unsigned integer, got '%s'", opt, v);
        c->seed = s;
        break;
    }
    case N_BITRATE: c->bitrate = (uint32_t)cli_long(opt, v, 300, 10000000); break;
    case N_GAP: c->slot_gap_ns = (uint64_t)(cli_double(opt, v, 0, 60000) * 1e6 + 0.5); break;
    case N_OVERHEAD: c->overhead_bytes = (int)cli_long(opt, v, 1, 255); break;
    case N_FAILS: c->fail_polls = (int)cli_long(opt, v, 1, 255); break;
    case N_127: c->allow_127 = 1; break;
    case N_LOSE_RECORD: c->lose_record = (int)cli_long(opt, v, 0, 65535); break;
    }
}

/* the rates the server's set_line (rtu.c) has a termios speed for: the POSIX and Linux B...
 * constants from 300 baud up that it lists */
static const long rtu_rates[] = {300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200,
                                 230400, 460800, 921600, 1000000, 2000000, 4000000};

void cli_rtu_line_check(const char *spec, long baud, int data_bits, char parity, int stop_bits)
{
    if (data_bits != 8)
        cli_usage_error("--rtu '%s': frame '%d%c%d': Modbus RTU has 8 data bits (MODBUS over Serial Line "
                        "V1.02, section 2.5.1); give 8E1, 8O1 or 8N2", spec, data_bits, parity, stop_bits);
    for (size_t i = 0; i < sizeof rtu_rates / sizeof rtu_rates[0]; i++)
        if (rtu_rates[i] == baud) return;
    char list[200] = "";
    for (size_t i = 0; i < sizeof rtu_rates / sizeof rtu_rates[0]; i++)
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s%ld", i ? ", " : "", rtu_rates[i]);
    cli_usage_error("--rtu '%s': baud rate %ld is not one a serial line can be set to (%s)", spec, baud, list);
}

void cli_rtu_allow_127_check(const mipemu_config *c, int n_rtu)
{
    if (c->allow_127 && n_rtu > 0)
        cli_usage_error("--allow-127 with --rtu: an FC16 of more than 123 registers (FC23: a write of "
                        "more than 121, a read of more than 125) is longer than the 256 bytes of an "
                        "RTU frame (MODBUS over Serial Line V1.02, section 2.5.1); use --allow-127 "
                        "without --rtu");
}

char *cli_script_line(FILE *f, char *buf, int size, int *lineno)
{
    if (!fgets(buf, size, f))
        return NULL;
    ++*lineno;
    char *hash = strchr(buf, '#');
    if (hash)
        *hash = 0;
    return buf;
}
