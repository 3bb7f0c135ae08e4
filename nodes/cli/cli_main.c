/*
 * cli_main.c — the commands of the edgewise program (libedgewise_cli.so,
 * loaded by main.c when a command runs): options every command takes, then
 * the subcommand (cmd_*.c).
 */
#include <malloc.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "edgewise/edgewise.h"

static int dispatch(int argc, char **argv, const char *usage) {
    if (argc < 2) {
        fputs(usage, stderr);
        return EW_EXIT_USAGE;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help")) {
        fputs(usage, stdout);
        return 0;
    }
    if (!strcmp(cmd, "--version")) {
        printf("edgewise %s\n", ew_version_string());
        return 0;
    }
    if (!strcmp(cmd, "denoise")) return cmd_denoise(argc - 1, argv + 1);
    if (!strcmp(cmd, "info")) return cmd_info(argc - 1, argv + 1);
    if (!strcmp(cmd, "compare")) return cmd_compare(argc - 1, argv + 1);
    if (!strcmp(cmd, "filter")) return cmd_filter(argc - 1, argv + 1);
    if (!strcmp(cmd, "dof")) return cmd_dof(argc - 1, argv + 1);
    if (!strcmp(cmd, "bench")) return cmd_bench(argc - 1, argv + 1);
    if (!strcmp(cmd, "train")) return cmd_train(argc - 1, argv + 1);
    if (!strcmp(cmd, "graph")) return cmd_graph(argc - 1, argv + 1);
    if (!strcmp(cmd, "nodes")) return cmd_nodes(argc - 1, argv + 1);
    fprintf(stderr, "edgewise: unknown command '%s' (try 'edgewise --help')\n", cmd);
    return EW_EXIT_USAGE;
}

/* Freed memory stays with the process for the next buffer. glibc serves
 * blocks above its mmap threshold (at most 32 MiB) with mmap and unmaps them
 * on free, so every image-sized buffer of every op, every file band and
 * every frame of a graph run came back as fresh page faults (and the kernel
 * zeroing the pages). From the heap, a freed buffer is reused as it is; the
 * process is short-lived or runs frame after frame of the same sizes, so
 * holding its peak costs nothing. The library itself sets nothing global:
 * this is the program's choice. */
static void keep_freed_memory(void) {
    mallopt(M_MMAP_MAX, 0);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

__attribute__((visibility("default"))) int ew_cli_main(int argc, char **argv, const char *usage);

int ew_cli_main(int argc, char **argv, const char *usage) {
    keep_freed_memory();
    if (!cli_take_timings(&argc, argv)) return EW_EXIT_USAGE;
    cli_install_signal_handlers();
    if (!cli_take_limits(&argc, argv)) return EW_EXIT_USAGE;
    int rc = dispatch(argc, argv, usage);
    cli_print_timings();
    return rc;
}
