/*
 * bench_ofx_keep: what the OFX plug-in's kept op saves per frame.
 *
 * Drives the bundle through the test host (tests/ofx) as a compositor
 * would: one instance of a denoiser plug-in, N frames at 1280x720 with the
 * Albedo, Normal and Depth clips connected, each frame other pixels (the
 * Cornell render mirrored and shifted). Two ways, alternating in blocks:
 *
 *   kept  the frames rendered one after the other (the plug-in keeps its
 *         device and op between them);
 *   new   kOfxActionPurgeCaches before every frame, so each render makes a
 *         new device and op: what every render did before the op was kept.
 *
 * Prints the per-frame wall and CPU (process) times of each way, the kept
 * figures without a block's first frame (which makes the op), checks both
 * ways give the same bits for every frame, and prints a hash of the
 * results (to compare with another build of the plug-in).
 *
 *   EW_OFX_BUNDLE=build-rel/plugin/Edgewise.ofx.bundle EW_SAMPLE_DIR=samples \
 *     build-rel/bin/bench_ofx_keep [--plugin kpcn] [--model 1] [--frames 8] [--blocks 3]
 *
 * --model: the kpcn parameter "model" (0 kpcn, 1 kpcn-small, 2 kpcn-large);
 * -1 leaves the plug-in's defaults (for other plug-ins).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ofx_fixtures.h"

#define W 1280
#define H 720

static double now(clockid_t c) {
    struct timespec t;
    clock_gettime(c, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Frame f: the sample mirrored across its edges to W x H, shifted by f. */
static float *tile(const float *src, int sw, int sh, int c, int f) {
    float *d = (float *)malloc((size_t)W * H * (size_t)c * sizeof(float));
    if (!d) abort();
    for (int y = 0; y < H; y++) {
        int ty = (y + 5 * f) % (2 * sh);
        if (ty >= sh) ty = 2 * sh - 1 - ty;
        for (int x = 0; x < W; x++) {
            int tx = (x + 11 * f) % (2 * sw);
            if (tx >= sw) tx = 2 * sw - 1 - tx;
            memcpy(d + ((size_t)y * W + (size_t)x) * (size_t)c, src + ((size_t)ty * (size_t)sw + (size_t)tx) * (size_t)c,
                   (size_t)c * sizeof(float));
        }
    }
    return d;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int main(int argc, char **argv) {
    const char *plugin = "kpcn";
    int model = 1, frames = 8, blocks = 3;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--plugin")) plugin = argv[i + 1];
        else if (!strcmp(argv[i], "--model")) model = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--frames")) frames = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--blocks")) blocks = atoi(argv[i + 1]);
        else {
            fprintf(stderr, "unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (frames < 2 || blocks < 1) {
        fprintf(stderr, "--frames >= 2, --blocks >= 1\n");
        return 2;
    }
    char err[512], id[96];
    snprintf(id, sizeof id, "org.edgewise.denoise.%s", plugin);
    const fx_sample *s = fx_cornell(err, sizeof err);
    if (!s) {
        fprintf(stderr, "%s\n", err);
        return 1;
    }
    float **rgba = calloc((size_t)frames, sizeof *rgba), **alb = calloc((size_t)frames, sizeof *alb);
    float **nrm = calloc((size_t)frames, sizeof *nrm), **dep = calloc((size_t)frames, sizeof *dep);
    float **first = calloc((size_t)frames, sizeof *first); /* each frame's result in the first block */
    double *wall[2], *cpu[2];
    for (int m = 0; m < 2; m++) {
        wall[m] = calloc((size_t)(frames * blocks), sizeof(double));
        cpu[m] = calloc((size_t)(frames * blocks), sizeof(double));
    }
    float *got = malloc((size_t)W * H * 4 * sizeof(float));
    if (!rgba || !alb || !nrm || !dep || !first || !got) abort();
    for (int f = 0; f < frames; f++) {
        rgba[f] = tile(s->rgba, s->w, s->h, 4, f);
        alb[f] = tile(s->albedo, s->w, s->h, 3, f);
        nrm[f] = tile(s->normal, s->w, s->h, 3, f);
        dep[f] = tile(s->ddepth, s->w, s->h, 1, f);
    }

    host_reset();
    host_cfg.num_cpus = 2;
    fx_plugin fx;
    if (fx_open(&fx, id, "OfxImageEffectContextGeneral", err, sizeof err)) {
        fprintf(stderr, "%s\n", err);
        fx_close(&fx);
        return 1;
    }
    if (model >= 0 && fx_set_param(&fx, "model", model)) {
        fprintf(stderr, "%s has no parameter model\n", id);
        fx_close(&fx);
        return 1;
    }
    OfxRectI whole = {0, 0, W, H};
    int mismatches = 0;
    for (int b = 0; b < blocks; b++) {
        for (int m = 0; m < 2; m++) { /* 0 kept, 1 new */
            hx_purge_caches(&fx.bundle, fx.index, fx.inst); /* every block starts without an op */
            for (int f = 0; f < frames; f++) {
                hx_clip_set_image(he_clip(fx.inst, "Source"), rgba[f], W, H, 4, 0, 0, 0);
                hx_clip_set_image(he_clip(fx.inst, "Albedo"), alb[f], W, H, 3, 0, 0, 0);
                hx_clip_set_image(he_clip(fx.inst, "Normal"), nrm[f], W, H, 3, 0, 0, 0);
                hx_clip_set_image(he_clip(fx.inst, "Depth"), dep[f], W, H, 1, 0, 0, 0);
                hx_output_prepare(he_clip(fx.inst, "Output"), whole, 4, 0);
                double w0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_PROCESS_CPUTIME_ID);
                if (m == 1) hx_purge_caches(&fx.bundle, fx.index, fx.inst);
                OfxStatus st = hx_render(&fx.bundle, fx.index, fx.inst, 1.0 + f, whole);
                double w1 = now(CLOCK_MONOTONIC), c1 = now(CLOCK_PROCESS_CPUTIME_ID);
                if (st != kOfxStatOK) {
                    fprintf(stderr, "render: status %d (%s)\n", st, host_st.last_message);
                    fx_close(&fx);
                    return 1;
                }
                wall[m][b * frames + f] = w1 - w0;
                cpu[m][b * frames + f] = c1 - c0;
                hx_output_read(he_clip(fx.inst, "Output"), whole, got);
                if (!first[f]) {
                    first[f] = malloc((size_t)W * H * 4 * sizeof(float));
                    if (!first[f]) abort();
                    memcpy(first[f], got, (size_t)W * H * 4 * sizeof(float));
                } else if (memcmp(first[f], got, (size_t)W * H * 4 * sizeof(float))) {
                    mismatches++;
                }
            }
        }
    }
    fx_close(&fx);

    /* kept without each block's first frame (it makes the op), and all */
    double kw[2], kc[2], nw, nc;
    {
        int n = 0;
        double *vw = malloc(sizeof(double) * (size_t)(frames * blocks)), *vc = malloc(sizeof(double) * (size_t)(frames * blocks));
        if (!vw || !vc) abort();
        for (int b = 0; b < blocks; b++)
            for (int f = 1; f < frames; f++) {
                vw[n] = wall[0][b * frames + f];
                vc[n++] = cpu[0][b * frames + f];
            }
        kw[0] = median(vw, n);
        kc[0] = median(vc, n);
        double sw = 0, sc = 0;
        for (int i = 0; i < frames * blocks; i++) {
            sw += wall[0][i];
            sc += cpu[0][i];
        }
        kw[1] = sw / (frames * blocks);
        kc[1] = sc / (frames * blocks);
        nw = median(wall[1], frames * blocks);
        nc = median(cpu[1], frames * blocks);
        free(vw);
        free(vc);
    }
    printf("plugin %s model %d, %dx%d, %d frames x %d blocks, host CPUs 2\n", plugin, model, W, H, frames, blocks);
    printf("new op every render : median %.1f ms wall, %.1f ms CPU per frame\n", 1e3 * nw, 1e3 * nc);
    printf("op kept (frames 2..): median %.1f ms wall, %.1f ms CPU per frame\n", 1e3 * kw[0], 1e3 * kc[0]);
    printf("op kept (mean, all) : %.1f ms wall, %.1f ms CPU per frame\n", 1e3 * kw[1], 1e3 * kc[1]);
    printf("kept / new (median) : %.3f wall, %.3f CPU\n", kw[0] / nw, kc[0] / nc);
    printf("bit-identical results across blocks and ways: %s (%d frames differ)\n", mismatches ? "NO" : "yes",
           mismatches);
    uint64_t hash = 14695981039346656037ull; /* FNV-1a over every frame's result */
    for (int f = 0; f < frames; f++) {
        const unsigned char *p = (const unsigned char *)first[f];
        for (size_t i = 0; i < (size_t)W * H * 4 * sizeof(float); i++) hash = (hash ^ p[i]) * 1099511628211ull;
    }
    printf("results hash %016llx\n", (unsigned long long)hash);
    for (int f = 0; f < frames; f++) {
        free(rgba[f]);
        free(alb[f]);
        free(nrm[f]);
        free(dep[f]);
        free(first[f]);
    }
    return mismatches ? 1 : 0;
}
