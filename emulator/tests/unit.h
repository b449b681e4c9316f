/* The emulator's C unit tests share this: CHECK / CHECK_EQ, one case at a time (run, or
 * g_case + end_case for a case named at run time), a summary line and JUnit XML (--junit FILE).
 * Define UNIT_CLASS (the JUnit classname) before including it. */
#ifndef EMU_TESTS_UNIT_H
#define EMU_TESTS_UNIT_H

#include <stdio.h>
#include <string.h>

static int g_pass, g_fail, g_case_failed;
static char g_case[160];
static char g_junit[1 << 16];
static size_t g_junit_len;

#define CHECK(cond) do { if (!(cond)) { \
    fprintf(stderr, "%s:%d: %s: check failed: %s\n", __FILE__, __LINE__, g_case, #cond); \
    g_case_failed = 1; } } while (0)
#define CHECK_EQ(a, b) do { long long a_ = (long long)(a), b_ = (long long)(b); if (a_ != b_) { \
    fprintf(stderr, "%s:%d: %s: %s == %lld, expected %s == %lld\n", __FILE__, __LINE__, g_case, #a, a_, #b, b_); \
    g_case_failed = 1; } } while (0)

/* ends the case named g_case: counted, one line, one JUnit testcase */
static void end_case(void)
{
    if (g_case_failed)
        g_fail++;
    else
        g_pass++;
    g_junit_len += (size_t)snprintf(g_junit + g_junit_len, sizeof g_junit - g_junit_len,
                                    "  <testcase classname=\"" UNIT_CLASS "\" name=\"%s\">%s</testcase>\n", g_case,
                                    g_case_failed ? "<failure message=\"see log\"/>" : "");
    printf("%s %s\n", g_case_failed ? "FAIL" : "ok  ", g_case);
    g_case_failed = 0;
}

static void run(const char *name, void (*fn)(void))
{
    snprintf(g_case, sizeof g_case, "%s", name);
    g_case_failed = 0;
    fn();
    end_case();
}

/* the summary line ("LABEL: N passed, N failed"), the JUnit file of --junit FILE; the exit code */
static int unit_finish(int argc, char **argv, const char *label)
{
    const char *junit = NULL;
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--junit") && i + 1 < argc)
            junit = argv[++i];
    printf("%s: %d passed, %d failed\n", label, g_pass, g_fail);
    if (junit) {
        FILE *f = fopen(junit, "w");
        if (f) {
            fprintf(f, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuite name=\"" UNIT_CLASS
                       "\" tests=\"%d\" failures=\"%d\">\n%.*s</testsuite>\n",
                    g_pass + g_fail, g_fail, (int)g_junit_len, g_junit);
            fclose(f);
        }
    }
    return g_fail ? 1 : 0;
}

#endif
