/*
 * edgewise train — the neural bilateral grid's trainer (docs/nbg.md) under
 * the one program users know. The trainer is its own binary, train_nbg:
 * it links the library's internal trainer, which the public API does not
 * carry. This command runs the train_nbg installed next to this program
 * with the same arguments, so `edgewise train --help` is train_nbg's.
 */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"

int cmd_train(int argc, char **argv) {
    char self[PATH_MAX], path[PATH_MAX + 16];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return cli_fail("train: cannot find this program's directory (%s)", strerror(errno));
    self[n] = '\0';
    char *slash = strrchr(self, '/');
    if (slash) *slash = '\0';
    snprintf(path, sizeof path, "%s/train_nbg", slash ? self : ".");
    if (access(path, X_OK) != 0)
        return cli_fail("train: no trainer at %s (it is built with the project: build/bin/train_nbg)", path);
    char **args = (char **)calloc((size_t)argc + 1, sizeof *args);
    if (!args) return cli_fail("train: out of memory");
    args[0] = path;
    for (int i = 1; i < argc; i++) args[i] = argv[i];
    execv(path, args);
    const int e = errno;
    free(args);
    return cli_fail("train: cannot run %s: %s", path, strerror(e));
}
