/*
 * What every command shares for the safety of the user's files and memory:
 * the read limits (--max-memory, --max-pixels, accepted by every command)
 * and SIGINT/SIGTERM/SIGHUP handling that removes the temporary a write is
 * filling before the process ends.
 */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "edgewise/nodes.h"

/* The handler only removes temporaries and exits: both async-signal-safe. */
static void on_signal(int sig) {
    ewio_remove_temporaries();      /* this program's own writes */
    ew_nodes_remove_temporaries(); /* the graph's write nodes (their ewio copy) */
    _exit(128 + sig);
}

void cli_install_signal_handlers(void) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction sa, old;
        /* a signal the caller ignores (nohup) stays ignored */
        if (sigaction(sigs[i], NULL, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_signal;
        sigemptyset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
}

/* "--opt VALUE" or "--opt=VALUE" at argv[i]: the value, and how many
 * arguments it took (0 when argv[i] is not --opt). */
static const char *option_value(int argc, char **argv, int i, const char *opt, int *took) {
    size_t n = strlen(opt);
    *took = 0;
    if (strncmp(argv[i], opt, n) != 0) return NULL;
    if (argv[i][n] == '=') {
        *took = 1;
        return argv[i] + n + 1;
    }
    if (argv[i][n] != '\0') return NULL;
    *took = i + 1 < argc ? 2 : 1;
    return i + 1 < argc ? argv[i + 1] : NULL;
}

int cli_take_limits(int *argc, char **argv) {
    int out = 0;
    for (int i = 0; i < *argc;) {
        int took = 0;
        const char *v;
        if ((v = option_value(*argc, argv, i, "--max-memory", &took)), took) {
            unsigned long long bytes = 0;
            if (!v || ewio_parse_size(v, &bytes) != 0) {
                fprintf(stderr, "edgewise: --max-memory expects a size such as 8G, 512M or 1000000 (bytes), got '%s'\n",
                        v ? v : "");
                return 0;
            }
            char buf[32];
            snprintf(buf, sizeof buf, "%llu", bytes);
            setenv("EDGEWISE_MAX_MEMORY", buf, 1);
        } else if ((v = option_value(*argc, argv, i, "--max-pixels", &took)), took) {
            char *end = NULL;
            errno = 0;
            long long px = v ? strtoll(v, &end, 10) : 0;
            if (!v || !*v || *end != '\0' || errno || px < 1 || px > (1LL << 28)) {
                fprintf(stderr, "edgewise: --max-pixels expects an integer in [1, 268435456], got '%s'\n", v ? v : "");
                return 0;
            }
            setenv("EDGEWISE_MAX_PIXELS", v, 1);
        } else if (!strcmp(argv[i], "--")) {
            /* everything after "--" is the command's own */
            while (i < *argc) argv[out++] = argv[i++];
            break;
        } else {
            argv[out++] = argv[i++];
            continue;
        }
        i += took;
    }
    *argc = out;
    argv[out] = NULL;
    return 1;
}

FILE *cli_fopen_regular(const char *path, const char **why) {
    /* O_NONBLOCK: opening a FIFO for reading would otherwise wait for a
     * writer forever; it is refused below like any non-regular file */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        *why = strerror(errno);
        return NULL;
    }
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        *why = S_ISDIR(st.st_mode) ? "is a directory" : "not a regular file";
        close(fd);
        return NULL;
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl >= 0) fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
    FILE *f = fdopen(fd, "rb");
    if (!f) {
        *why = strerror(errno);
        close(fd);
    }
    return f;
}

int cli_check_image_output(const char *path) {
    if (!path || !*path) return cli_fail("-o needs a file name (got an empty one)");
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    static const char *const exts[] = {"exr", "png", "tif", "tiff", "jpg", "jpeg"};
    int known = 0;
    for (size_t i = 0; dot && dot != base && i < sizeof exts / sizeof exts[0]; i++)
        known |= !strcasecmp(dot + 1, exts[i]);
    /* refused before any work, as the write itself would refuse after it */
    if (!known)
        return cli_fail("cannot write '%s': %s (use .exr, .png, .tif, .tiff, .jpg or .jpeg)", path,
                        dot && dot != base ? "unsupported extension" : "no file extension");
    struct stat st;
    if (lstat(path, &st) == 0 && !S_ISREG(st.st_mode) && !S_ISLNK(st.st_mode) && !S_ISDIR(st.st_mode))
        return cli_fail("cannot write '%s': not a regular file", path);
    return cli_check_writable(path);
}
