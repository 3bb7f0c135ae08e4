/*
 * edgewise — the command-line front end. Subcommands live in cmd_*.c; this
 * file dispatches and owns --help / --version.
 */
#include <malloc.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "edgewise/edgewise.h"

static const char usage[] =
    "usage: edgewise <command> [options]\n"
    "\n"
    "Denoising and edge-aware filtering for Monte Carlo renders.\n"
    "\n"
    "commands:\n"
    "  denoise IN -o OUT   denoise a render (Cycles multilayer EXR, or EXR/PNG/TIFF colour)\n"
    "  info IN             list the layers, passes and metadata of an image file\n"
    "  compare TEST REF    PSNR and SSIM of TEST against REF (tone-mapped)\n"
    "  filter IN -o OUT    one of the library's filters on a pass (filter --help lists them)\n"
    "  dof IN -o OUT       depth of field from the depth pass and Blender camera values\n"
    "  bench DIR -o OUT    every method on a directory of renders: quality and time (CSV)\n"
    "  train --data DIR    train a neural bilateral grid model (runs train_nbg; models/nbg/README.md)\n"
    "  graph run FILE      run a node graph file (JSON; docs/graphs.md)\n"
    "  nodes               list every node type with its ports and parameters\n"
    "\n"
    "  edgewise <command> --help   options of a command\n"
    "  --max-memory SIZE           any command: refuse inputs whose pixels would take more\n"
    "                              (e.g. 8G; default 3/4 of the physical memory)\n"
    "  --max-pixels N              any command: refuse larger images (default and at most 2^28)\n"
    "  --timings[=N]               any command: print where the time went (start-up, read,\n"
    "                              compute, write; =N: also the fastest of N warm runs)\n"
    "  edgewise --version          library version\n";

static int dispatch(int argc, char **argv) {
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

int main(int argc, char **argv) {
    keep_freed_memory();
    if (!cli_take_timings(&argc, argv)) return EW_EXIT_USAGE;
    cli_install_signal_handlers();
    if (!cli_take_limits(&argc, argv)) return EW_EXIT_USAGE;
    int rc = dispatch(argc, argv);
    cli_print_timings();
    return rc;
}
