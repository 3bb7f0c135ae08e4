/*
 * op_half.c — EW_FORMAT_HALF inputs for every method. A method lists the
 * images it reads as halves itself (ew_op_type.half_inputs); any other
 * half view is replaced, for the method, by a float copy the op owns
 * (kept across commits of its size), packed before each execute. The
 * caller's view stays in op->given.
 */
#include "src/backend.h"
#include "src/op.h"

/* Whether image i is a half view the op packs into floats: one the method
 * does not read as halves itself (EW_IMAGE_HALF_IN_PLACE, from half_inputs). */
static int packed_here(const ew_op *op, int i) {
    uint32_t fl = 0;
    if (!op->has_image[i] || op->given[i].format != EW_FORMAT_HALF) return 0;
    ew_method_image_flags(op->type->kind, op->type->name, i, &fl);
    return !(fl & EW_IMAGE_HALF_IN_PLACE);
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

void ew_op_half_execute(ew_op *op) {
    for (int i = 0; i < op->type->num_images; i++) {
        const ew_image *g = &op->given[i];
        if (op->half_copy[i]) ew_dev_view_rows(op->dev, g, g->channels, 0, g->height, 0, g->width, op->half_copy[i]);
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
