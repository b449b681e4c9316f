/* libFuzzer target: the config parser (plcrt format and OpenPLC mbconfig.cfg) on arbitrary
 * bytes. Checks: no crash / sanitizer report; a refused config gives exactly one line that
 * starts with the file name. */
#include "plcrt.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char err[256];
    plcrt_t *rt = plcrt_new(plcrt_linked_program(), err, sizeof err);
    if (!rt) abort();
    plcrt_set_log(rt, NULL, NULL);
    if (plcrt_load_config_mem(rt, "fuzz.cfg", data, size) != 0) {
        const char *msg = plcrt_errmsg(rt);
        if (strncmp(msg, "fuzz.cfg:", 9) != 0 || strchr(msg, '\n') || !strstr(msg, "error: ")) {
            fprintf(stderr, "bad error line: '%s'\n", msg);
            abort();
        }
    }
    plcrt_free(rt);
    return 0;
}
