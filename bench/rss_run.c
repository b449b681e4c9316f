/* rss_run: runs a command and writes its peak memory (ru_maxrss of that child, KiB) to a file.
 *
 *   rss_run OUTFILE CMD [ARGS...]
 *
 * Why not getrusage from Python directly: Linux carries the high-water RSS of the process image
 * that called exec() over into the child's ru_maxrss, so a child forked from a 20 MB Python
 * reports at least 20 MB. This launcher is small; its own share is a few hundred KiB.
 * SIGTERM / SIGINT are passed on to the child. Writes "maxrss_kib=N exit=S" to OUTFILE and exits
 * with the child's status (128 + signal if it was killed by one). */
#define _GNU_SOURCE
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

static volatile pid_t child;

static void pass_on(int sig)
{
    if (child > 0)
        kill(child, sig);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: rss_run OUTFILE CMD [ARGS...]\n");
        return 2;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = pass_on;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    pid_t pid = fork();
    if (pid < 0) {
        fprintf(stderr, "rss_run: error: fork: %s\n", strerror(errno));
        return 1;
    }
    if (pid == 0) {
        signal(SIGTERM, SIG_DFL);
        signal(SIGINT, SIG_DFL);
        execvp(argv[2], argv + 2);
        fprintf(stderr, "rss_run: error: %s: %s\n", argv[2], strerror(errno));
        _exit(127);
    }
    child = pid;
    int status;
    struct rusage ru;
    while (wait4(pid, &status, 0, &ru) < 0) {
        if (errno != EINTR) {
            fprintf(stderr, "rss_run: error: wait4: %s\n", strerror(errno));
            return 1;
        }
    }
    int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    FILE *f = fopen(argv[1], "w");
    if (!f) {
        fprintf(stderr, "rss_run: error: %s: %s\n", argv[1], strerror(errno));
        return 1;
    }
    fprintf(f, "maxrss_kib=%ld exit=%d\n", ru.ru_maxrss, code);
    fclose(f);
    return code;
}
