/*
 * edgewise — the command-line program. It is small on purpose: --version,
 * --help and a bare `edgewise` are answered here, by a process that loads
 * only libedgewise; every command is in libedgewise_cli.so (cli_main.c),
 * loaded when one is run. That library brings OpenEXR and OpenColorIO;
 * OpenImageIO and the ~260 shared libraries it pulls in come only with a
 * PNG, TIFF or JPEG file (nodes/io/codec.h), and their loading and
 * relocation is then most of a command's start-up (measured with --timings).
 */
#define _GNU_SOURCE /* dladdr */
#include <dlfcn.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "edgewise/edgewise.h"

/* Exit codes as cli.h: 1 the work failed, 2 the command line was wrong. */
#define EXIT_FAIL 1
#define EXIT_USAGE 2

static const char usage[] =
    "usage: edgewise <command> [options]\n"
    "\n"
    "Denoising and edge-aware filtering for Monte Carlo renders.\n"
    "\n"
    "commands:\n"
    "  denoise IN -o OUT   denoise a render (Cycles multilayer EXR, or EXR/PNG/TIFF/JPEG colour)\n"
    "  info IN             list the layers, passes and metadata of an image file\n"
    "  compare TEST REF    PSNR and SSIM of TEST against REF (tone-mapped)\n"
    "  filter IN -o OUT    one of the library's filters on a pass (filter --help lists them)\n"
    "  dof IN -o OUT       depth of field from the depth pass and Blender camera values\n"
    "  bench DIR -o OUT    every method on a directory of renders: quality and time (CSV)\n"
    "  train --data DIR    train a neural bilateral grid model (runs train_nbg; models/nbg/README.md)\n"
    "  graph run FILE      run a node graph file (JSON; docs/graphs.md)\n"
    "  graph check FILE    validate a graph file without running it: nodes, parameters,\n"
    "                      connections, frame files and outputs\n"
    "  nodes               list every node type with its ports and parameters\n"
    "\n"
    "\n"
    "Images: EXR (multilayer), PNG, TIFF and JPEG in; the output's extension picks the\n"
    "format: .exr, .png, .tif/.tiff, .jpg/.jpeg (PNG and JPEG as display images).\n"
    "Exit codes: 0 done, 1 the work failed (input, output, memory), 2 a wrong command line.\n"
    "\n"
    "  edgewise <command> --help   options of a command\n"
    "  --max-memory SIZE           any command: refuse inputs whose pixels would take more\n"
    "                              (e.g. 8G; default 3/4 of the physical memory)\n"
    "  --max-pixels N              any command: refuse larger images (default and at most 2^28)\n"
    "  --timings[=N]               any command: print where the time went (start-up, read,\n"
    "                              compute, write; =N: also the fastest of N warm runs)\n"
    "  edgewise --version          library version\n";


typedef int (*cli_main_fn)(int argc, char **argv, const char *usage);

/* dlopen of libedgewise_cli.so in the directory of file, then sub. */
static void *load_beside(const char *file, const char *sub) {
    const char *slash = strrchr(file, '/');
    if (!slash) return NULL;
    char path[4096];
    const int n = snprintf(path, sizeof path, "%.*s%s/libedgewise_cli.so", (int)(slash - file), file, sub);
    return n > 0 && (size_t)n < sizeof path ? dlopen(path, RTLD_NOW | RTLD_LOCAL) : NULL;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fputs(usage, stderr);
        return EXIT_USAGE;
    }
    if (argc == 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help"))) {
        fputs(usage, stdout);
        return 0;
    }
    if (argc == 2 && !strcmp(argv[1], "--version")) {
        printf("edgewise %s\n", ew_version_string());
        return 0;
    }
    /* Next to libedgewise, wherever the loader found it (this program's
     * RUNPATH, $ORIGIN/../lib, or an installed prefix). By full path: a
     * bare name would be searched with the RUNPATH of dlopen's caller,
     * which under AddressSanitizer is its interceptor, not this program. */
    void *lib = NULL;
    Dl_info info;
    union {
        const char *(*fn)(void);
        void *p;
    } in_lib = {ew_version_string}; /* an address inside libedgewise */
    if (dladdr(in_lib.p, &info) && info.dli_fname) lib = load_beside(info.dli_fname, "");
    /* then where the RUNPATH points, for a libedgewise loaded from
     * elsewhere (LD_LIBRARY_PATH) */
    char exe[4096];
    const ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (!lib && len > 0) {
        exe[len] = '\0';
        lib = load_beside(exe, "/../lib");
    }
    if (!lib) lib = dlopen("libedgewise_cli.so", RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "edgewise: cannot load the commands: %s\n", dlerror());
        return EXIT_FAIL;
    }
    cli_main_fn cli_main = NULL;
    *(void **)&cli_main = dlsym(lib, "ew_cli_main");
    if (!cli_main) {
        fprintf(stderr, "edgewise: libedgewise_cli.so has no ew_cli_main: %s\n", dlerror());
        return EXIT_FAIL;
    }
    return cli_main(argc, argv, usage);
}
