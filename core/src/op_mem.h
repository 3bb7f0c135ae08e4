/*
 * op_mem.h — the device memory of an op that runs on any device
 * (docs/backends.md): one device allocation carved into the buffers its
 * kernels use, and the host staging that views move through when the
 * device has memory of its own. Made at commit, reused by every execute.
 */
#ifndef EW_OP_MEM_H
#define EW_OP_MEM_H

#include "src/op.h"

/* A buffer to carve: *at gets `floats` floats of the allocation, or NULL
 * when floats is 0 (an absent optional input). */
typedef struct ew_op_buf {
    float **at;
    size_t floats;
} ew_op_buf;

typedef struct ew_op_mem {
    float *dmem;  /* the device allocation */
    float *stage; /* host staging, or NULL when views need none */
} ew_op_mem;

/* Allocate bufs[0..n) in one block of op->dev, and staging for views of
 * up to stage_channels channels at the op's image size. Fails with
 * EW_ERR_OUT_OF_MEMORY, naming the method, the size and the MiB asked for,
 * having freed what it allocated. */
ew_result ew_op_mem_alloc(ew_op *op, ew_op_mem *m, const ew_op_buf *bufs, int n, int stage_channels);
/* Free both; m becomes empty (freeing an empty one is a no-op). */
void ew_op_mem_free(ew_op *op, ew_op_mem *m);

/* The first c channels of the image in slot `name` into the device buffer
 * dst, and the device buffer src into that image. Nothing is moved (EW_OK)
 * when the slot is unset or the buffer NULL. */
ew_result ew_op_put(ew_op *op, const ew_op_mem *m, const char *name, int c, float *dst);
ew_result ew_op_get(ew_op *op, const ew_op_mem *m, const float *src, int c, const char *name);

#endif
