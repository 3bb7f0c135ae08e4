/*
 * mirror.h — frames mirrored left-right or up-down, for a network run on a
 * mirrored frame and averaged with the others (kpcn's "passes"). A network
 * is not mirror-symmetric: its errors on a frame and on the same frame
 * mirrored differ, and their mean keeps what the runs share.
 *
 * MIRROR_SWAP mirrors interleaved planes in place along one axis: each work
 * item swaps a pixel of the first half with its image in the second, so no
 * two items touch the same pixel. MIRROR_ADD gathers one run's output back
 * through the mirror it ran under into an accumulation plane; its last call
 * (the unmirrored run, mode EW_MIRROR_LAST) writes (acc + out) * scale over
 * the output, each pixel reading only itself.
 */
#ifndef EW_KERNELS_MIRROR_H
#define EW_KERNELS_MIRROR_H

#include "kernels/compat.h"

/* A long and eight ints after two pointers: no padding (a device copies the
 * struct as bytes, and the launch-grid check reads every word of it as a
 * possible pointer). */
typedef struct ew_mirror_swap_args {
    float *p;      /* width * height * channels, interleaved */
    long channels;
    int width, height;
    int dw, dh;    /* the domain: (width / 2) x height left-right, width x (height / 2) up-down */
    int axis;      /* 0 left-right, 1 up-down */
    int unused;
} ew_mirror_swap_args;

EW_HD void ew_mirror_swap_px(int x, int y, const ew_mirror_swap_args *a) {
    const int mx = a->axis == 0 ? a->width - 1 - x : x, my = a->axis == 0 ? y : a->height - 1 - y;
    float *p = a->p + ((long)y * a->width + x) * a->channels;
    float *q = a->p + ((long)my * a->width + mx) * a->channels;
    for (long c = 0; c < a->channels; c++) {
        const float t = p[c];
        p[c] = q[c];
        q[c] = t;
    }
}

enum { EW_MIRROR_FIRST = 0, EW_MIRROR_MORE = 1, EW_MIRROR_LAST = 2 };

typedef struct ew_mirror_add_args {
    float *out;    /* one run's RGB output, laid out as its mirrored frame */
    float *acc;    /* RGB, the unmirrored frame */
    int width, height;
    int mx, my;    /* the run's mirror: 1 = mirrored along x (left-right), y (up-down) */
    int mode;      /* FIRST acc = out', MORE acc += out', LAST out = (acc + out) * scale (mx = my = 0) */
    float scale;
} ew_mirror_add_args;

EW_HD void ew_mirror_add_px(int x, int y, const ew_mirror_add_args *a) {
    const long j = (long)y * a->width + x;
    const long m = (long)(a->my ? a->height - 1 - y : y) * a->width + (a->mx ? a->width - 1 - x : x);
    for (int c = 0; c < 3; c++) {
        if (a->mode == EW_MIRROR_LAST)
            a->out[j * 3 + c] = (a->acc[j * 3 + c] + a->out[j * 3 + c]) * a->scale;
        else if (a->mode == EW_MIRROR_FIRST)
            a->acc[j * 3 + c] = a->out[m * 3 + c];
        else
            a->acc[j * 3 + c] += a->out[m * 3 + c];
    }
}

#endif
