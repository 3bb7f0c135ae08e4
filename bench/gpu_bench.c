/*
 * gpu_bench.c — milliseconds per frame of every denoiser and filter at
 * 1280x720 and 2560x1440, so GPU figures can be taken whenever a GPU is
 * available (the paper's are RTX 2080 timings at 1280x720: 9.4 ms for
 * 2-layer 1-grid, 16.5 ms for 3 grids).
 *
 *   gpu_bench [--device cuda|cpu|default] [--frames N] [--sizes WxH,...]
 *             [--method NAME] [--device-images]
 *
 * Inputs are synthetic (a noisy gradient image, plausible albedo, normals
 * and depth), every image slot of a method filled, parameters at their
 * defaults. One warm-up frame (first launches, allocations at commit), then
 * the mean of N executes. Host views by default: a frame includes packing
 * and copying the inputs to the GPU and the output back, as an application
 * handing host pixels sees it. --device-images passes device pointers (as
 * an OFX host rendering on CUDA does) and times the GPU work alone, waiting
 * for the stream after each frame.
 *
 * Exit status: 0; 77 when --device cuda is asked for and there is no GPU
 * (the reason is printed); 2 for a wrong command line.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "edgewise/edgewise.h"
#include "src/backend.h"
#include "src/internal.h"

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static unsigned rng = 1u;
static float rnd(void) {
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

/* Synthetic content for an image slot, by its name. */
static void fill(float *p, int w, int h, int c, const char *name) {
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int k = 0; k < c; k++) {
                float v;
                if (strstr(name, "normal")) v = k == 2 ? 0.8f : 0.4f * (rnd() - 0.5f);
                else if (strstr(name, "depth")) v = 1.0f + 9.0f * (float)y / (float)h;
                else if (strstr(name, "vector") || strstr(name, "motion")) v = 0.5f;
                else if (strstr(name, "albedo")) v = 0.2f + 0.6f * (float)((x / 64 + y / 64) % 2);
                else v = (float)x / (float)w * (0.5f + rnd()); /* noisy gradient */
                p[((size_t)y * w + x) * (size_t)c + (size_t)k] = v;
            }
}

typedef struct {
    void *host[16];
    void *dev[16];
    int n;
} buffers;

static void free_buffers(ew_device *dev, buffers *b) {
    for (int i = 0; i < b->n; i++) {
        free(b->host[i]);
        if (b->dev[i]) dev->backend->mem_free(dev, b->dev[i]);
    }
    b->n = 0;
}

/* One method at one size: ms per frame, or a negative value with why. */
static double bench_one(ew_device *dev, const char *kind, const char *name, int w, int h, int frames,
                        char *why, size_t why_len) {
    ew_op *op = NULL;
    ew_result r = ew_op_create(dev, name, &op);
    buffers b;
    memset(&b, 0, sizeof b);
    int32_t nimg = 0;
    for (int32_t i = 0; i < ew_method_count(kind); i++) {
        const char *nm;
        int32_t ni, np;
        if (ew_method_get(kind, i, &nm, NULL, &ni, &np) == EW_OK && !strcmp(nm, name)) nimg = ni;
    }
    for (int32_t i = 0; r == EW_OK && i < nimg && b.n < 16; i++) {
        ew_image_info info;
        ew_method_image(kind, name, i, &info);
        const int c = info.min_channels;
        const size_t bytes = (size_t)w * h * (size_t)c * sizeof(float);
        float *host = (float *)malloc(bytes);
        if (!host) {
            r = EW_ERR_OUT_OF_MEMORY;
            break;
        }
        fill(host, w, h, c, info.name);
        void *data = host;
        b.host[b.n] = host;
        b.dev[b.n] = NULL;
        if (dev->device_images) {
            b.dev[b.n] = dev->backend->mem_alloc(dev, bytes);
            if (!b.dev[b.n] || dev->backend->mem_upload(dev, b.dev[b.n], host, bytes) != EW_OK) r = EW_ERR_OUT_OF_MEMORY;
            data = b.dev[b.n];
        }
        b.n++;
        ew_image v = ew_image_packed((float *)data, w, h, c);
        if (r == EW_OK) r = ew_op_set_image(op, info.name, &v);
    }
    if (r == EW_OK) r = ew_op_commit(op);
    double ms = -1.0;
    for (int frame = -1; r == EW_OK && frame < frames; frame++) {
        const double t0 = now_ms();
        r = ew_op_execute(op);
        if (r == EW_OK && dev->device_images) r = dev->backend->sync(dev, 1); /* the GPU work, not its queueing */
        if (frame == 0) ms = 0.0; /* frame -1 warms up */
        if (frame >= 0) ms += now_ms() - t0;
    }
    if (r != EW_OK) {
        snprintf(why, why_len, "%s: %s", ew_result_string(r), ew_device_last_error(dev));
        ms = -1.0;
    } else {
        ms /= frames;
    }
    ew_op_destroy(op);
    free_buffers(dev, &b);
    return ms;
}

static int usage(void) {
    fprintf(stderr, "usage: gpu_bench [--device cuda|cpu|default] [--frames N] [--sizes WxH,...] [--method NAME] "
                    "[--device-images]\n");
    return 2;
}

int main(int argc, char **argv) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.type = EW_DEVICE_CUDA;
    int frames = 20;
    const char *sizes = "1280x720,2560x1440", *only = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--device") && i + 1 < argc) {
            const char *t = argv[++i];
            desc.type = !strcmp(t, "cpu") ? EW_DEVICE_CPU : !strcmp(t, "default") ? EW_DEVICE_DEFAULT : EW_DEVICE_CUDA;
            if (strcmp(t, "cpu") && strcmp(t, "cuda") && strcmp(t, "default")) return usage();
        } else if (!strcmp(argv[i], "--frames") && i + 1 < argc) {
            frames = atoi(argv[++i]);
            if (frames < 1) return usage();
        } else if (!strcmp(argv[i], "--sizes") && i + 1 < argc) {
            sizes = argv[++i];
        } else if (!strcmp(argv[i], "--method") && i + 1 < argc) {
            only = argv[++i];
        } else if (!strcmp(argv[i], "--device-images")) {
            desc.device_images = 1;
        } else {
            return usage();
        }
    }
    if (desc.device_images && desc.type != EW_DEVICE_CUDA) {
        fprintf(stderr, "gpu_bench: --device-images needs --device cuda\n");
        return 2;
    }
    ew_device *dev = NULL;
    ew_result r = ew_device_create(&desc, &dev);
    if (r != EW_OK) {
        printf("gpu_bench: no %s device: %s (%s)\n", desc.type == EW_DEVICE_CPU ? "CPU" : "CUDA", ew_result_string(r),
               ew_backend_unavailable_reason(desc.type));
        return desc.type == EW_DEVICE_CUDA ? 77 : 1;
    }
    printf("device: %s%s, %d frames after one warm-up, %s views\n", dev->backend->name,
           ew_device_get_type(dev) == EW_DEVICE_CPU ? " (CPU)" : "", frames,
           desc.device_images ? "device-pointer" : "host");
    if (desc.type == EW_DEVICE_DEFAULT && ew_device_get_type(dev) == EW_DEVICE_CPU)
        printf("(fell back to the CPU: %s)\n", ew_backend_unavailable_reason(EW_DEVICE_CUDA));
    printf("%-10s %-12s %-11s %10s\n", "kind", "method", "size", "ms/frame");
    const char *kinds[] = {"denoiser", "filter"};
    for (int k = 0; k < 2; k++)
        for (int32_t i = 0; i < ew_method_count(kinds[k]); i++) {
            const char *name;
            if (ew_method_get(kinds[k], i, &name, NULL, NULL, NULL) != EW_OK) continue;
            if (only && strcmp(only, name)) continue;
            for (const char *s = sizes; s && *s;) {
                int w = 0, h = 0;
                if (sscanf(s, "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0) return usage();
                char label[32], why[600] = "";
                snprintf(label, sizeof label, "%dx%d", w, h);
                const double ms = bench_one(dev, kinds[k], name, w, h, frames, why, sizeof why);
                if (ms >= 0.0) printf("%-10s %-12s %-11s %10.2f\n", kinds[k], name, label, ms);
                else printf("%-10s %-12s %-11s %10s  %s\n", kinds[k], name, label, "-", why);
                fflush(stdout);
                s = strchr(s, ',');
                if (s) s++;
            }
        }
    ew_device_destroy(dev);
    return 0;
}
