/* mipemu-sim: runs the mipemu core in virtual time from a script and prints the trace.
 * Same seed and script: the same bytes on every machine (for docs and sequence diagrams). */
#include "cli_config.h"
#include "mipemu.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PROG "mipemu-sim"

static const char USAGE[] =
    "usage: " PROG " [options] [SCRIPT]   (SCRIPT or stdin)\n"
    "Runs an emulated MIP network in virtual time and prints its JSON-lines trace to stdout,\n"
    "plus one \"reply\" line per request with the registers read.\n"
    "\n"
    "Network options as for mip-emulator: --stations N, --mode static|dynamic,\n"
    "--static-registers N, --loss-down P, --loss-up P, --burst L, --seed S, --bitrate B,\n"
    "--slot-gap-ms MS, --overhead-bytes N, --fail-polls N, --allow-127, --lose-record N.\n"
    "\n"
    "Script lines ('#' starts a comment):\n"
    "  at SECONDS                  advance virtual time to SECONDS (never backwards)\n"
    "  after SECONDS               advance by SECONDS\n"
    "  trm S fcN ARGS              a request to the TRM-810 of station S\n"
    "  mdp UNIT fcN ARGS           a request to the MDP-810 with that unit id\n"
    "    fc3 ADDR COUNT | fc4 ADDR COUNT | fc6 ADDR VALUE | fc16 ADDR VALUE... |\n"
    "    fc23 READADDR READCOUNT WRITEADDR VALUE...\n";

static const char *g_file = "<stdin>";
static int g_line;

__attribute__((noreturn, format(printf, 2, 3))) static void script_error(int col, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "%s:%d:%d: error: ", g_file, g_line, col);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    exit(2);
}

static void trace_out(void *user, const char *line, size_t len)
{
    (void)user;
    fwrite(line, 1, len, stdout);
}

/* script tokens with their columns */
typedef struct { char *s; int col; } tok_t;

static long tok_num(const tok_t *t, long lo, long hi)
{
    char *e;
    errno = 0;
    long v = strtol(t->s, &e, 0);
    if (errno || e == t->s || *e || v < lo || v > hi)
        script_error(t->col, "expected an integer %ld..%ld, got '%s'", lo, hi, t->s);
    return v;
}

static double tok_seconds(const tok_t *t)
{
    char *e;
    errno = 0;
    double v = strtod(t->s, &e);
    if (errno || e == t->s || *e || !(v >= 0 && v <= 1e7))
        script_error(t->col, "expected seconds 0..1e7, got '%s'", t->s);
    return v;
}

static void put16(uint8_t *p, long v) { p[0] = (uint8_t)(v >> 8); p[1] = (uint8_t)v; }

/* the quantity, the byte count and the values of a write of n registers (fc16, and fc23's
 * write part) at w; returns the bytes written */
static size_t put_regs(uint8_t *w, const tok_t *vals, int n)
{
    put16(w, n);
    w[2] = (uint8_t)(2 * n);
    for (int i = 0; i < n; i++)
        put16(w + 3 + 2 * i, tok_num(&vals[i], 0, 65535));
    return 3 + 2 * (size_t)n;
}

static void request(mipemu_net *net, tok_t *tk, int nt, unsigned tid)
{
    int is_mdp = !strcmp(tk[0].s, "mdp");
    if (nt < 3)
        script_error(tk[0].col, "expected '%s NUMBER fcN ...'", tk[0].s);
    long who = tok_num(&tk[1], is_mdp ? 0 : 1, is_mdp ? 255 : mipemu_net_stations(net));
    int ep = is_mdp ? MIPEMU_EP_MDP : (int)who;
    unsigned unit = is_mdp ? (unsigned)who : 1;
    uint8_t req[MIPEMU_FRAME_MAX];
    uint8_t *pdu = req + 7;
    size_t plen = 0;
    int fc;
    if (sscanf(tk[2].s, "fc%d", &fc) != 1)
        script_error(tk[2].col, "expected fc3, fc4, fc6, fc16 or fc23, got '%s'", tk[2].s);
    int nargs = nt - 3;
    tok_t *a = tk + 3;
    pdu[0] = (uint8_t)fc;
    if (fc == 3 || fc == 4 || fc == 6) {
        if (nargs != 2)
            script_error(tk[2].col, "fc%d takes 2 numbers", fc);
        put16(pdu + 1, tok_num(&a[0], 0, 65535));
        put16(pdu + 3, tok_num(&a[1], 0, 65535));
        plen = 5;
    } else if (fc == 16) {
        if (nargs < 2 || nargs > 128)
            script_error(tk[2].col, "fc16 takes an address and 1..127 values");
        put16(pdu + 1, tok_num(&a[0], 0, 65535));
        plen = 3 + put_regs(pdu + 3, a + 1, nargs - 1);
    } else if (fc == 23) {
        if (nargs < 4 || nargs > 130)
            script_error(tk[2].col, "fc23 takes read address, read count, write address and 1..127 values");
        put16(pdu + 1, tok_num(&a[0], 0, 65535));
        put16(pdu + 3, tok_num(&a[1], 0, 65535));
        put16(pdu + 5, tok_num(&a[2], 0, 65535));
        plen = 7 + put_regs(pdu + 7, a + 3, nargs - 3);
    } else {
        script_error(tk[2].col, "function code %d is not one the script knows (3, 4, 6, 16, 23)", fc);
    }
    put16(req, tid);
    put16(req + 2, 0);
    put16(req + 4, (long)plen + 1);
    req[6] = (uint8_t)unit;
    uint8_t out[MIPEMU_RESPONSE_MAX];
    long rl = mipemu_handle(net, ep, req, plen + 7, out, sizeof out);
    if (rl < 9) {
        printf("{\"t\":%llu,\"ev\":\"reply\",\"tid\":%u,\"close\":true}\n",
               (unsigned long long)mipemu_net_now(net), tid);
        return;
    }
    printf("{\"t\":%llu,\"ev\":\"reply\",\"tid\":%u,\"exc\":%u", (unsigned long long)mipemu_net_now(net), tid,
           out[7] & 0x80 ? out[8] : 0);
    if (!(out[7] & 0x80) && (fc == 3 || fc == 4 || fc == 23)) {
        printf(",\"regs\":[");
        for (int i = 0; i < out[8] / 2; i++)
            printf("%s%u", i ? "," : "", (unsigned)(out[9 + 2 * i] << 8 | out[10 + 2 * i]));
        printf("]");
    }
    printf("}\n");
}

int main(int argc, char **argv)
{
    cli_prog = PROG;
    mipemu_config c;
    mipemu_config_default(&c);
    const char *script = NULL;
    for (int i = 1; i < argc; i++) {
        const char *o = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
#define NEEDV() do { if (!v) cli_usage_error("option %s needs a value", o); i++; } while (0)
        if (!strcmp(o, "--help")) { fputs(USAGE, stdout); return 0; }
        else if (o[0] == '-' && o[1] == '-' && cli_net_option_find(o + 2) >= 0) {
            int k = cli_net_option_find(o + 2);
            if (cli_net_options[k].has_value) NEEDV();
            cli_net_option_apply(&c, k, cli_net_options[k].has_value ? v : NULL);
        }
        else if (o[0] == '-' && o[1]) cli_usage_error("unknown option '%s'", o);
        else if (script) cli_usage_error("unexpected argument '%s'", o);
        else script = o;
#undef NEEDV
    }
    char err[160];
    mipemu_net *net = mipemu_net_new(&c, err, sizeof err);
    if (!net)
        cli_usage_error("%s", err);
    FILE *f = stdin;
    if (script && strcmp(script, "-")) {
        f = fopen(script, "r");
        if (!f) {
            fprintf(stderr, PROG ": error: cannot read %s: %s\n", script, strerror(errno));
            return 2;
        }
        g_file = script;
    }
    mipemu_net_set_trace(net, trace_out, NULL);
    char line[4096];
    unsigned tid = 0;
    while (cli_script_line(f, line, sizeof line, &g_line)) {
        tok_t tk[140];
        int nt = 0;
        for (char *p = line; *p;) {
            while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
                *p++ = 0;
            if (!*p)
                break;
            if (nt == 140)
                script_error((int)(p - line) + 1, "too many words on one line");
            tk[nt].s = p;
            tk[nt].col = (int)(p - line) + 1;
            nt++;
            while (*p && *p != ' ' && *p != '\t' && *p != '\r' && *p != '\n')
                p++;
        }
        if (nt == 0)
            continue;
        if (!strcmp(tk[0].s, "at") || !strcmp(tk[0].s, "after")) {
            if (nt != 2)
                script_error(tk[0].col, "'%s' takes one number of seconds", tk[0].s);
            uint64_t d = (uint64_t)(tok_seconds(&tk[1]) * 1e9 + 0.5);
            uint64_t t = tk[0].s[1] == 't' ? d : mipemu_net_now(net) + d;
            if (mipemu_net_advance(net, t) != 0)
                script_error(tk[1].col, "time %s s lies before the current %.9f s", tk[1].s,
                             (double)mipemu_net_now(net) / 1e9);
        } else if (!strcmp(tk[0].s, "trm") || !strcmp(tk[0].s, "mdp")) {
            request(net, tk, nt, ++tid & 0xFFFF);
        } else {
            script_error(tk[0].col, "unknown command '%s' (at, after, trm, mdp)", tk[0].s);
        }
    }
    if (f != stdin)
        fclose(f);
    mipemu_net_free(net);
    return 0;
}
