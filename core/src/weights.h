/*
 * weights.h — the versioned binary format of trained parameters (GuideNet
 * convolutions, pyramid filter weight tables), validated on load.
 *
 * Layout (little-endian):
 *   magic "EWWEIGHT" (8 bytes), u32 version (1), u32 arch length, arch
 *   string (e.g. "guidenet-rt-3grid"), u32 tensor count, then per tensor:
 *   u32 name length, name, u32 rank (1..4), u32 dims[rank], f32 data[prod],
 *   and finally u32 CRC-32 (IEEE) of every byte before it.
 * Loading checks magic, version, sizes against the buffer, finiteness of
 * every value and the checksum, so a damaged or foreign file is an error,
 * never a wrong image.
 */
#ifndef EW_WEIGHTS_H
#define EW_WEIGHTS_H

#include <stddef.h>
#include <stdint.h>

#define EW_WEIGHTS_VERSION 1u
#define EW_WEIGHTS_MAX_RANK 4
#define EW_WEIGHTS_MAX_NAME 64

typedef struct ew_tensor {
    char name[EW_WEIGHTS_MAX_NAME];
    uint32_t rank;
    uint32_t dims[EW_WEIGHTS_MAX_RANK];
    size_t count;
    float *data;
} ew_tensor;

typedef struct ew_weights {
    char arch[EW_WEIGHTS_MAX_NAME];
    uint32_t num_tensors;
    ew_tensor *tensors;
} ew_weights;

/* Parse a weights file held in memory. On failure returns non-zero and
 * writes a one-line reason to err. The result owns its memory. */
int ew_weights_parse(const void *bytes, size_t size, ew_weights *out, char *err, size_t errlen);
void ew_weights_free(ew_weights *w);
/* Tensor by name with the expected shape (rank dims given); NULL + message
 * when absent or shaped differently. */
const ew_tensor *ew_weights_find(const ew_weights *w, const char *name, uint32_t rank, const uint32_t *dims,
                                 char *err, size_t errlen);
/* Serialise; *out is malloc'd (caller frees). Returns 0 on success. */
int ew_weights_serialize(const ew_weights *w, void **out, size_t *size);
/* CRC-32 (IEEE, zlib's crc32) of data: the checksum of both weights formats. */
uint32_t ew_crc32(const void *data, size_t size);

#endif
