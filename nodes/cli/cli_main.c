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

/* Freed memory stays with the process for the next buffer. glibc starts
 * with a 128 KiB mmap threshold, raised only as mapped blocks are freed, and
 * trims the heap's top above twice that: image bands, passes and scratch
 * buffers came back as fresh page faults (the kernel zeroing every page)
 * phase after phase and frame after frame. Blocks up to 32 MiB (glibc's
 * largest threshold) now come from the heap and are reused; larger ones are
 * still mapped and returned on free. Turning mmap off altogether (M_MMAP_MAX
 * 0) cut the faults of a graph run further but its peak RSS grew from frame
 * to frame (heap fragmentation: 613 MB after 4 frames, 1249 MB after 6 for
 * auto at 1280x720), which a long shot cannot afford. The library itself
 * sets nothing global: this is the program's choice. */
static void keep_freed_memory(void) {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

/* Between phases of a one-shot command: the heap's free blocks go back to
 * the system. A phase that frees a frame's worth (the input pass once it is
 * copied out, the op's buffers after it ran) is followed by one whose large
 * buffers are mapped, not carved from the heap: kept, the freed memory
 * would add to that phase's peak instead of serving it. */
void cli_return_freed_memory(void) { malloc_trim(0); }

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
