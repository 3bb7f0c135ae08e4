/*
 * frames.c — frame patterns in file names, as renderers and compositors
 * write sequences: a run of '#' is the frame number zero-padded to the
 * run's length (Blender: "render_####.exr" -> "render_0042.exr"), and a
 * printf-style "%0Nd" or "%d" is the same with N digits (Nuke, ffmpeg:
 * "render_%04d.exr"). The first pattern in the file name counts; a pattern
 * in a directory name is not one.
 */
#include <ctype.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

/* The frame pattern of `path`: where it starts, how many characters it
 * takes and the digits it pads to. 0 when there is none. */
static int find_pattern(const char *path, size_t *at, size_t *len, int *width) {
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    for (const char *c = base; *c; c++) {
        if (*c == '#') {
            size_t run = 0;
            while (c[run] == '#') run++;
            *at = (size_t)(c - path);
            *len = run;
            *width = (int)run;
            return 1;
        }
        if (*c == '%') {
            const char *d = c + 1;
            int w = 0;
            if (*d == '0') d++;
            while (isdigit((unsigned char)*d) && w < 100) w = w * 10 + (*d++ - '0');
            if (*d == 'd' && w <= 9) {
                *at = (size_t)(c - path);
                *len = (size_t)(d + 1 - c);
                *width = w > 0 ? w : 1;
                return 1;
            }
        }
    }
    return 0;
}

int ew_path_has_pattern(const char *path) {
    size_t at, len;
    int width;
    return path && find_pattern(path, &at, &len, &width);
}

int ew_frame_path(const char *pattern, int frame, char *out, size_t len) {
    size_t at, plen;
    int width;
    if (!find_pattern(pattern, &at, &plen, &width)) return snprintf(out, len, "%s", pattern) < (int)len;
    int k = snprintf(out, len, "%.*s%0*d%s", (int)at, pattern, width, frame, pattern + at + plen);
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
    size_t at, plen;
    int width;
    if (!find_pattern(pattern, &at, &plen, &width)) return 0; /* none in the file name */
    const char *h = pattern + at;
    size_t pre = (size_t)(h - base), run = (size_t)width;
    const char *suffix = h + plen;
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
