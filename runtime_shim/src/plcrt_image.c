/* The located image: OpenPLC's address space, one array per area and size. */
#include "plcrt_internal.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void *fail(char *err, size_t errlen, const char *msg, char area, char size,
                  const long *parts, int nparts)
{
    if (err && errlen) {
        if (nparts == 2)
            snprintf(err, errlen, "%%%c%c%ld.%ld: %s", area, size, parts[0], parts[1], msg);
        else if (nparts == 1)
            snprintf(err, errlen, "%%%c%c%ld: %s", area, size, parts[0], msg);
        else
            snprintf(err, errlen, "%%%c%c: %s", area, size, msg);
    }
    return NULL;
}

void *plcrt_image_locate(plcrt_image_t *img, char area, char size, const long *parts,
                         int nparts, char *err, size_t errlen)
{
    area = (char)toupper((unsigned char)area);
    size = (char)toupper((unsigned char)size);
    if (area != 'I' && area != 'Q' && area != 'M')
        return fail(err, errlen, "unknown area (I, Q or M)", area, size, parts, nparts);
    if (size == 'X') {
        if (nparts != 2)
            return fail(err, errlen, "a bit address needs two parts a.b", area, size, parts, nparts);
        if (parts[0] < 0 || parts[0] >= PLCRT_IMAGE_SIZE || parts[1] < 0 || parts[1] > 7)
            return fail(err, errlen, "outside the image (a < 1024, b < 8)", area, size, parts, nparts);
        if (area == 'I') return &img->ix[parts[0]][parts[1]];
        if (area == 'Q') return &img->qx[parts[0]][parts[1]];
        return fail(err, errlen, "%MX is not in the image (OpenPLC has none)", area, size, parts, nparts);
    }
    if (nparts != 1)
        return fail(err, errlen, "a byte/word/double/long address has one part", area, size, parts, nparts);
    if (parts[0] < 0 || parts[0] >= PLCRT_IMAGE_SIZE)
        return fail(err, errlen, "outside the image (n < 1024)", area, size, parts, nparts);
    long n = parts[0];
    switch (size) {
    case 'B':
        if (area == 'I') return &img->ib[n];
        if (area == 'Q') return &img->qb[n];
        break;
    case 'W':
        if (area == 'I') return &img->iw[n];
        if (area == 'Q') return &img->qw[n];
        return &img->mw[n];
    case 'D':
        if (area == 'M') return &img->md[n];
        break;
    case 'L':
        if (area == 'M') return &img->ml[n];
        break;
    default:
        return fail(err, errlen, "unknown size (X, B, W, D or L)", area, size, parts, nparts);
    }
    return fail(err, errlen, "not in the image (OpenPLC's space: %IX %QX %IB %QB %IW %QW %MW %MD %ML)",
                area, size, parts, nparts);
}

int plcrt_parse_address(const char *text, char *area, char *size, long parts[2], int *nparts)
{
    const char *p = text;
    while (isspace((unsigned char)*p)) p++;
    if (*p == '%') p++;
    if (!*p || !p[1]) return -1;
    *area = (char)toupper((unsigned char)p[0]);
    *size = (char)toupper((unsigned char)p[1]);
    if (!strchr("IQM", *area) || !strchr("XBWDL", *size)) return -1;
    p += 2;
    *nparts = 0;
    for (;;) {
        if (!isdigit((unsigned char)*p)) return -1;
        char *end;
        long v = strtol(p, &end, 10);
        if (*nparts >= 2) return -1;
        parts[(*nparts)++] = v;
        p = end;
        if (*p == '.') { p++; continue; }
        break;
    }
    while (isspace((unsigned char)*p)) p++;
    return *p ? -1 : 0;
}
