/*
 * op_memory.c — ew_op_memory: what a commit would allocate, asked before
 * the caller has the pixels (a front reads an 8K file's header, asks, and
 * refuses before reading gigabytes it could not denoise). Each method
 * answers from the size computation its commit uses.
 */
#include "src/op.h"

ew_result ew_op_memory(ew_op *op, int32_t width, int32_t height, uint64_t *bytes) {
    if (!op || !bytes) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    *bytes = 0;
    if (width <= 0 || height <= 0)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "memory estimate: invalid size %dx%d", width, height);
    if (!op->type->memory)
        return ew__fail(op->dev, EW_ERR_UNSUPPORTED, "%s '%s' gives no memory estimate", op->type->kind,
                        op->type->name);
    *bytes = op->type->memory(op, width, height);
    if (*bytes) *bytes += ew_harm_memory(op, width, height) /* the do-no-harm stage around it */
                          + ew_op_half_memory(op, width, height); /* float copies of half inputs */
    if (!*bytes)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "%s '%s': no memory estimate for %dx%d with these parameters",
                        op->type->kind, op->type->name, width, height);
    return EW_OK;
}
