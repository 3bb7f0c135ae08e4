/*
 * cli_timings.c — `--timings` (any command): where a one-shot run's time
 * goes, as a user waits for it. Start-up is the time from the process's
 * creation to main (the dynamic loader mapping the libraries and their
 * constructors: what a pipeline calling edgewise once per frame pays every
 * frame); read, compute and write are the commands' own phases. With
 * --timings=N the method is run N more times on the same op after the
 * timed run and the fastest of those is printed as "warm": the in-process
 * time of the same work, for the ratio in one run.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"

cli_timings cli_timing;

double cli_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Seconds since the process was created: its start time in clock ticks
 * since boot (/proc/self/stat, field 22) against CLOCK_BOOTTIME; -1 when
 * /proc is not there. Resolution one tick (10 ms). */
static double seconds_since_start(void) {
    FILE *fp = fopen("/proc/self/stat", "r");
    if (!fp) return -1.0;
    char buf[1024];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    fclose(fp);
    buf[n] = '\0';
    const char *p = strrchr(buf, ')'); /* the command name may hold spaces */
    if (!p) return -1.0;
    unsigned long long start = 0;
    /* after ")": state (field 3) ... starttime (field 22) */
    if (sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %*u %*u %*d %*d %*d %*d %*d %*d %llu",
               &start) != 1)
        return -1.0;
    struct timespec ts;
    if (clock_gettime(CLOCK_BOOTTIME, &ts) != 0) return -1.0;
    long tick = sysconf(_SC_CLK_TCK);
    if (tick <= 0) return -1.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec - (double)start / (double)tick;
}

int cli_take_timings(int *argc, char **argv) {
    cli_timing.t_main = cli_seconds();
    cli_timing.startup = seconds_since_start();
    int out = 0;
    for (int i = 0; i < *argc; i++) {
        if (!strcmp(argv[i], "--")) { /* the rest is the command's own */
            while (i < *argc) argv[out++] = argv[i++];
            break;
        }
        if (!strcmp(argv[i], "--timings")) {
            cli_timing.enabled = 1;
            continue;
        }
        if (!strncmp(argv[i], "--timings=", 10)) {
            char *end = NULL;
            long v = strtol(argv[i] + 10, &end, 10);
            if (!argv[i][10] || *end || v < 0 || v > 1000) {
                fprintf(stderr, "edgewise: --timings=N expects N warm runs in [0, 1000], got '%s'\n", argv[i] + 10);
                return 0;
            }
            cli_timing.enabled = 1;
            cli_timing.warm_runs = (int)v;
            continue;
        }
        argv[out++] = argv[i];
    }
    argv[out] = NULL;
    *argc = out;
    cli_timing.warm = -1.0;
    return 1;
}

void cli_print_timings(void) {
    if (!cli_timing.enabled) return;
    const double total = cli_seconds() - cli_timing.t_main + (cli_timing.startup > 0 ? cli_timing.startup : 0.0);
    fprintf(stderr, "edgewise: timings: start-up %.3f s, read %.3f s, compute %.3f s, write %.3f s, total %.3f s",
            cli_timing.startup, cli_timing.read, cli_timing.compute, cli_timing.write, total);
    if (cli_timing.warm >= 0.0)
        fprintf(stderr, ", warm compute %.3f s (fastest of %d more runs in the process)", cli_timing.warm,
                cli_timing.warm_runs);
    fputc('\n', stderr);
}
