/* The network options both emulator fronts accept (mip-emulator, mipemu-sim): one table, one
 * parser, so their names, ranges and messages cannot drift apart. Private to emulator/src. */
#ifndef MIPEMU_CLI_CONFIG_H
#define MIPEMU_CLI_CONFIG_H

#include "mipemu.h"

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

#endif
