/*
 * op_half.c — EW_FORMAT_HALF inputs for every method. A method lists the
 * images it reads as halves itself (ew_op_type.half_inputs); any other
 * half view is replaced, for the method, by a float copy the op owns
 * (kept across commits of its size), packed before each execute. The
 * caller's view stays in op->given.
 */
#include "src/op.h"

#include <stdlib.h>
#include <string.h>

static int reads_half(const ew_op_type *t, const char *name) {
    for (const char *const *l = t->half_inputs; l && *l; l++)
        if (!strcmp(*l, name)) return 1;
    return 0;
}

/* Whether image i is a half view the op packs into floats. */
static int packed_here(const ew_op *op, int i) {
    return op->has_image[i] && op->given[i].format == EW_FORMAT_HALF && !reads_half(op->type, op->type->images[i].name);
}

static void drop(ew_op *op, int i) {
    ew_host_free(op->half_copy[i]);
    op->half_copy[i] = NULL;
    op->half_copy_floats[i] = 0;
}

ew_result ew_op_half_commit(ew_op *op) {
    for (int i = 0; i < op->type->num_images; i++) {
        if (!packed_here(op, i)) {
            drop(op, i);
            if (op->has_image[i]) op->images[i] = op->given[i];
            continue;
        }
        const ew_image *g = &op->given[i];
        if (op->dev->device_images)
            return ew__fail(op->dev, EW_ERR_UNSUPPORTED,
                            "image '%s': %s '%s' reads it as floats, and an EW_FORMAT_HALF view of device memory is not "
                            "packed on the host: pass EW_FORMAT_FLOAT",
                            op->type->images[i].name, op->type->kind, op->type->name);
        const size_t floats = (size_t)g->width * (size_t)g->height * (size_t)g->channels;
        if (op->half_copy_floats[i] != floats) {
            drop(op, i);
            op->half_copy[i] = (float *)ew_host_alloc(floats * sizeof(float));
            if (!op->half_copy[i])
                return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory: a float copy of half image '%s' (%.1f MiB)",
                                op->type->images[i].name, (double)floats * sizeof(float) / 1048576.0);
            op->half_copy_floats[i] = floats;
        }
        op->images[i] = ew_image_packed(op->half_copy[i], g->width, g->height, g->channels);
    }
    return EW_OK;
}

typedef struct {
    const ew_image *src;
    float *dst;
} pack_job;

static void pack_rows(void *ctx, int64_t y0, int64_t y1, int tid) {
    (void)tid;
    const pack_job *j = (const pack_job *)ctx;
    const int w = j->src->width, c = j->src->channels;
    for (int64_t y = y0; y < y1; y++) {
        float *d = j->dst + (size_t)y * (size_t)w * (size_t)c;
        if (ew__pixel_stride(j->src) == 2 * (int64_t)c) { /* the row's pixels back to back: one run */
            ew__halves_to_floats((const unsigned short *)(const void *)ew__pixel(j->src, 0, (int)y), d, (size_t)w * (size_t)c);
            continue;
        }
        for (int x = 0; x < w; x++) {
            const unsigned short *p = (const unsigned short *)(const void *)ew__pixel(j->src, x, (int)y);
            for (int k = 0; k < c; k++) *d++ = ew_half_to_float(p[k]);
        }
    }
}

void ew_op_half_execute(ew_op *op) {
    for (int i = 0; i < op->type->num_images; i++) {
        if (!op->half_copy[i]) continue;
        pack_job j = {&op->given[i], op->half_copy[i]};
        ew_pool_run(op->dev->pool, op->given[i].height, 0, pack_rows, &j);
    }
}

uint64_t ew_op_half_memory(const ew_op *op, int w, int h) {
    uint64_t bytes = 0;
    for (int i = 0; i < op->type->num_images; i++)
        if (packed_here(op, i)) bytes += (uint64_t)w * (uint64_t)h * (uint64_t)op->given[i].channels * sizeof(float);
    return bytes;
}

void ew_op_half_release(ew_op *op) {
    for (int i = 0; i < EW_OP_MAX_IMAGES; i++) drop(op, i);
}
