/* op_mem.c — an op's device buffers and staging (op_mem.h). */
#include "src/op_mem.h"

#include <stdlib.h>

#include "src/backend.h"

/* The op's image size: every set image has it (ew_op_commit checks). */
static size_t op_pixels(const ew_op *op, int *w, int *h) {
    for (int i = 0; i < op->type->num_images; i++)
        if (op->has_image[i]) {
            *w = op->images[i].width;
            *h = op->images[i].height;
            return (size_t)*w * (size_t)*h;
        }
    *w = *h = 0;
    return 0;
}

ew_result ew_op_mem_alloc(ew_op *op, ew_op_mem *m, const ew_op_buf *bufs, int n, int stage_channels) {
    ew_device *dev = op->dev;
    int w, h;
    const size_t px = op_pixels(op, &w, &h);
    size_t floats = 0;
    for (int i = 0; i < n; i++) floats += bufs[i].floats;
    const size_t stage = ew_dev_stage_floats(dev, px, stage_channels);
    m->dmem = (float *)ew_dev_alloc(dev, floats * sizeof(float));
    m->stage = stage ? (float *)malloc(stage * sizeof(float)) : NULL;
    if (!m->dmem || (stage && !m->stage)) {
        ew_op_mem_free(op, m);
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory: %s '%s' at %dx%d needs %.1f MiB", op->type->kind,
                        op->type->name, w, h, (double)(floats + stage) * sizeof(float) / 1048576.0);
    }
    float *p = m->dmem;
    for (int i = 0; i < n; i++) {
        *bufs[i].at = bufs[i].floats ? p : NULL;
        p += bufs[i].floats;
    }
    return EW_OK;
}

void ew_op_mem_free(ew_op *op, ew_op_mem *m) {
    ew_dev_free(op->dev, m->dmem);
    free(m->stage);
    m->dmem = NULL;
    m->stage = NULL;
}

ew_result ew_op_put(ew_op *op, const ew_op_mem *m, const char *name, int c, float *dst) {
    const ew_image *img = ew_op_image(op, name);
    return img && dst ? ew_dev_put_view(op->dev, img, c, dst, m->stage) : EW_OK;
}

ew_result ew_op_get(ew_op *op, const ew_op_mem *m, const float *src, int c, const char *name) {
    const ew_image *img = ew_op_image(op, name);
    return img && src ? ew_dev_get_view(op->dev, src, c, img, m->stage) : EW_OK;
}
