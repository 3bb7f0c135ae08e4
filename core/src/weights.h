/*
 * weights.h — the one container of trained parameters (GuideNet and KPCN
 * convolutions, pyramid filter weight tables), validated on load.
 *
 * Layout (little-endian):
 *   magic "EWWEIGHT" (8 bytes), u32 version (1), u32 arch length, arch
 *   string (e.g. "nbg-2layer-3grid"), u32 tensor count, then per tensor:
 *   u32 name length, name, u32 rank (1..4), u32 dims[rank], f32 data[prod],
 *   and finally u32 CRC-32 (zlib's crc32) of every byte before it.
 * Pyramid tables were once written with the magic "EWPYRWTS" and this same
 * layout; such files are still read.
 * Loading checks magic, version, sizes against the buffer, finiteness of
 * every value and the checksum, so a damaged or foreign file is an error,
 * never a wrong image. What the tensors must hold is the reader's check
 * (its architecture string, names, shapes and ranges).
 */
#ifndef EW_WEIGHTS_H
#define EW_WEIGHTS_H

#include <stddef.h>
#include <stdint.h>

#define EW_WEIGHTS_VERSION 1u
#define EW_WEIGHTS_MAX_RANK 4
#define EW_WEIGHTS_MAX_NAME 64
#define EW_WEIGHTS_MAX_ARCH 256

typedef struct ew_tensor {
    char name[EW_WEIGHTS_MAX_NAME];
    uint32_t rank;
    uint32_t dims[EW_WEIGHTS_MAX_RANK];
    size_t count;
    float *data;
} ew_tensor;

typedef struct ew_weights {
    char arch[EW_WEIGHTS_MAX_ARCH];
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
/* Tensor by name, whatever its shape; NULL when absent. */
const ew_tensor *ew_weights_tensor(const ew_weights *w, const char *name);
/* Serialise into buf when cap is enough; returns the file's size either
 * way (buf NULL: just the size). */
size_t ew_weights_write(const ew_weights *w, void *buf, size_t cap);
/* Serialise; *out is malloc'd (caller frees). Returns 0 on success. */
int ew_weights_serialize(const ew_weights *w, void **out, size_t *size);
/* A 5x5 convolution layer l of a network's file: "conv<l>.weight"
 * [cout, cin, 5, 5] and "conv<l>.bias" [cout], at w_off and b_off of the
 * network's parameter vector. get copies them from w into params (non-zero
 * with err when absent or shaped otherwise); put describes them in t[0..2),
 * pointing into params, for ew_weights_serialize. */
int ew_weights_get_conv(const ew_weights *w, int l, int cin, int cout, float *params, size_t w_off, size_t b_off,
                        char *err, size_t errlen);
void ew_weights_put_conv(ew_tensor t[2], int l, int cin, int cout, const float *params, size_t w_off, size_t b_off);
/* CRC-32 (IEEE, zlib's crc32) of data: the container's checksum. */
uint32_t ew_crc32(const void *data, size_t size);

#endif
