/*
 * frames.c — frame patterns as Blender writes them: a run of '#' in the
 * file name is the frame number, zero-padded to the run's length
 * ("render_####.exr" -> "render_0042.exr").
 */
#include <ctype.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

int ew_path_has_pattern(const char *path) { return path && strchr(path, '#') != NULL; }

int ew_frame_path(const char *pattern, int frame, char *out, size_t len) {
    const char *h = strchr(pattern, '#');
    if (!h) return snprintf(out, len, "%s", pattern) < (int)len;
    size_t run = 0;
    while (h[run] == '#') run++;
    int k = snprintf(out, len, "%.*s%0*d%s", (int)(h - pattern), pattern, (int)run, frame, h + run);
    return k >= 0 && (size_t)k < len;
}

static int cmp_int(const void *a, const void *b) {
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

int ew_frames_on_disk(const char *pattern, int **out, int *count) {
    *out = NULL;
    *count = 0;
    char dir[4096];
    const char *slash = strrchr(pattern, '/');
    const char *base = slash ? slash + 1 : pattern;
    if (slash == pattern) snprintf(dir, sizeof dir, "/");
    else if (slash) snprintf(dir, sizeof dir, "%.*s", (int)(slash - pattern), pattern);
    else snprintf(dir, sizeof dir, ".");
    const char *h = strchr(base, '#');
    if (!h) return 0; /* a '#' in a directory name is not a frame pattern */
    size_t pre = (size_t)(h - base), run = 0;
    while (h[run] == '#') run++;
    const char *suffix = h + run;
    size_t suf = strlen(suffix);
    DIR *d = opendir(dir);
    if (!d) return 0;
    int cap = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        const char *name = e->d_name;
        size_t len = strlen(name);
        if (len < pre + run + suf || strncmp(name, base, pre) != 0 || strcmp(name + len - suf, suffix) != 0) continue;
        size_t nd = len - pre - suf;
        if (nd < run || nd > 9) continue;
        int ok = 1, frame = 0;
        for (size_t i = 0; i < nd; i++) {
            char c = name[pre + i];
            if (!isdigit((unsigned char)c)) ok = 0;
            else frame = frame * 10 + (c - '0');
        }
        /* more digits than the run only for numbers that need them */
        if (!ok || (nd > run && name[pre] == '0')) continue;
        if (*count == cap) {
            cap = cap ? cap * 2 : 16;
            int *nf = (int *)realloc(*out, (size_t)cap * sizeof(int));
            if (!nf) {
                closedir(d);
                free(*out);
                *out = NULL;
                *count = 0;
                return 1;
            }
            *out = nf;
        }
        (*out)[(*count)++] = frame;
    }
    closedir(d);
    if (*count) qsort(*out, (size_t)*count, sizeof(int), cmp_int);
    return 0;
}
