/* The network options both emulator fronts accept (mip-emulator, mipemu-sim): one table, one
 * parser, so their names, ranges and messages cannot drift apart. Private to emulator/src. */
#ifndef MIPEMU_CLI_CONFIG_H
#define MIPEMU_CLI_CONFIG_H

#include "mipemu.h"

#include <stdio.h>

/* The front's name for messages ("mip-emulator: error: ..."). Set before any other call. */
extern const char *cli_prog;

/* Prints "<prog>: error: <message> (see --help)" and exits with status 2. */
__attribute__((noreturn, format(printf, 1, 2))) void cli_usage_error(const char *fmt, ...);

/* Integer / real option values in [lo, hi], or a usage error naming the option. */
long cli_long(const char *opt, const char *s, long lo, long hi);
double cli_double(const char *opt, const char *s, double lo, double hi);

/* The network options, without the leading "--"; has_value says whether one follows. */
typedef struct cli_net_option { const char *name; int has_value; } cli_net_option;
extern const cli_net_option cli_net_options[];
extern const int cli_net_option_count;

/* -1: `name` (without "--") is not a network option; else its index in cli_net_options. */
int cli_net_option_find(const char *name);

/* Applies network option `index` with `value` (NULL for a flag) to `c`; bad values end in
 * cli_usage_error. */
void cli_net_option_apply(mipemu_config *c, int index, const char *value);

/* The line settings of an --rtu line (spec as given, for the message) that Modbus RTU can have:
 * 8 data bits (MODBUS over Serial Line Specification and Implementation Guide V1.02, section
 * 2.5.1) and a rate a serial line can be set to (the termios B... constants the server sets; any
 * other was silently taken as 19,200 by the tty while the timing used the rate given). Else a
 * usage error naming the reason. */
void cli_rtu_line_check(const char *spec, long baud, int data_bits, char parity, int stop_bits);

/* --allow-127 together with an --rtu line: a usage error (an FC16 of 124..127 registers, an FC23
 * write of 122..127 or a read answer of 126..127 is longer than an RTU frame may be). */
void cli_rtu_allow_127_check(const mipemu_config *c, int n_rtu);

/* The next line of the script file f into buf (size bytes) with its '#' comment cut off, and
 * *lineno counted up; NULL at the end of the file. */
char *cli_script_line(FILE *f, char *buf, int size, int *lineno);

#endif
