/* Config parser (see plcrt_master.c for now). */
#include "plcrt_internal.h"
