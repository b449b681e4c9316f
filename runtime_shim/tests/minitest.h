/* A very small C test runner: TEST() functions, CHECK macros, a summary line
 * "N passed, M failed" and JUnit XML (--junit FILE). Include once per test program. */
#ifndef MINITEST_H
#define MINITEST_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef void (*mt_fn)(void);
typedef struct { const char *name; mt_fn fn; } mt_case;

static mt_case mt_cases[256];
static int mt_n_cases;
static int mt_failed_now;
static char mt_msg[1024];

#define TEST(tname)                                                       \
    static void tname(void);                                              \
    __attribute__((constructor)) static void mt_reg_##tname(void)         \
    {                                                                     \
        mt_cases[mt_n_cases].name = #tname;                               \
        mt_cases[mt_n_cases++].fn = tname;                                \
    }                                                                     \
    static void tname(void)

#define CHECK(cond)                                                                   \
    do {                                                                              \
        if (!(cond)) {                                                                \
            if (!mt_failed_now)                                                       \
                snprintf(mt_msg, sizeof mt_msg, "%s:%d: CHECK(%s) failed", __FILE__,  \
                         __LINE__, #cond);                                            \
            fprintf(stderr, "  %s:%d: CHECK(%s) failed\n", __FILE__, __LINE__, #cond); \
            mt_failed_now = 1;                                                        \
        }                                                                             \
    } while (0)

#define CHECK_EQ(a, b)                                                                       \
    do {                                                                                     \
        long long mt_a = (long long)(a), mt_b = (long long)(b);                              \
        if (mt_a != mt_b) {                                                                  \
            if (!mt_failed_now)                                                              \
                snprintf(mt_msg, sizeof mt_msg, "%s:%d: %s == %lld, expected %s == %lld",    \
                         __FILE__, __LINE__, #a, mt_a, #b, mt_b);                            \
            fprintf(stderr, "  %s:%d: %s == %lld, expected %s == %lld\n", __FILE__, __LINE__, \
                    #a, mt_a, #b, mt_b);                                                     \
            mt_failed_now = 1;                                                               \
        }                                                                                    \
    } while (0)

#define CHECK_STR_CONTAINS(hay, needle)                                                   \
    do {                                                                                  \
        const char *mt_h = (hay), *mt_nd = (needle);                                      \
        if (!mt_h || !strstr(mt_h, mt_nd)) {                                              \
            if (!mt_failed_now)                                                           \
                snprintf(mt_msg, sizeof mt_msg, "%s:%d: '%.400s' does not contain '%.200s'",\
                         __FILE__, __LINE__, mt_h ? mt_h : "(null)", mt_nd);              \
            fprintf(stderr, "  %s:%d: '%s' does not contain '%s'\n", __FILE__, __LINE__,   \
                    mt_h ? mt_h : "(null)", mt_nd);                                       \
            mt_failed_now = 1;                                                            \
        }                                                                                 \
    } while (0)

static void mt_xml_escape(FILE *f, const char *s)
{
    for (; *s; s++) {
        switch (*s) {
        case '<': fputs("&lt;", f); break;
        case '>': fputs("&gt;", f); break;
        case '&': fputs("&amp;", f); break;
        case '"': fputs("&quot;", f); break;
        default: fputc(*s, f);
        }
    }
}

static int mt_main(int argc, char **argv, const char *suite)
{
    const char *junit = NULL, *only = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--junit") && i + 1 < argc) junit = argv[++i];
        else only = argv[i];
    }
    int passed = 0, failed = 0;
    static char msgs[256][1024];
    static double secs[256];
    static int fails[256];
    for (int i = 0; i < mt_n_cases; i++) {
        if (only && strcmp(only, mt_cases[i].name)) continue;
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        mt_failed_now = 0;
        mt_msg[0] = 0;
        mt_cases[i].fn();
        clock_gettime(CLOCK_MONOTONIC, &t1);
        secs[i] = (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) / 1e9;
        fails[i] = mt_failed_now;
        snprintf(msgs[i], sizeof msgs[i], "%s", mt_msg);
        printf("%s %s\n", mt_failed_now ? "FAIL" : "ok  ", mt_cases[i].name);
        if (mt_failed_now) failed++; else passed++;
    }
    printf("%s: %d passed, %d failed\n", suite, passed, failed);
    if (junit) {
        FILE *f = fopen(junit, "w");
        if (f) {
            fprintf(f, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
            fprintf(f, "<testsuite name=\"%s\" tests=\"%d\" failures=\"%d\">\n", suite,
                    passed + failed, failed);
            for (int i = 0; i < mt_n_cases; i++) {
                if (only && strcmp(only, mt_cases[i].name)) continue;
                fprintf(f, "  <testcase classname=\"%s\" name=\"%s\" time=\"%.4f\"", suite,
                        mt_cases[i].name, secs[i]);
                if (fails[i]) {
                    fprintf(f, "><failure message=\"");
                    mt_xml_escape(f, msgs[i]);
                    fprintf(f, "\"/></testcase>\n");
                } else {
                    fprintf(f, "/>\n");
                }
            }
            fprintf(f, "</testsuite>\n");
            fclose(f);
        }
    }
    return failed ? 1 : 0;
}

#endif
