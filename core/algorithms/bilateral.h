/*
 * bilateral.h — host side of the joint bilateral filters: building a model
 * from user parameters, packing views into the kernels' buffers (with the
 * missing-sample convention), and the brute-force and separable runs.
 */
#ifndef EW_ALGORITHMS_BILATERAL_H
#define EW_ALGORITHMS_BILATERAL_H

#include <stddef.h>

#include "kernels/bilateral.h"
#include "src/internal.h"

/* The packers and unpackers run over bands of rows on dev's threads (every
 * filter's execute alike; dev NULL: on the calling thread); the result does
 * not depend on the thread count.
 *
 * Pack a view of C channels into the kernels' layout (r, g, b, mask): the
 * first 3 channels (zeros after C), mask 1; a pixel with any non-finite
 * channel is missing: all 0. Returns the number of missing pixels. */
long ew_bf_pack_image(ew_device *dev, const ew_image *img, int C, float *dst);
/* Unpack a result into a view of C channels: colour divided by the mask;
 * pixels with no valid sample in reach (mask 0) are written as 0. A 4th
 * channel (alpha) is copied from alpha_from (the input view) unfiltered.
 * Returns how many pixels were written as 0. */
long ew_bf_unpack_image(ew_device *dev, const float *src, int C, const ew_image *img, const ew_image *alpha_from);
/* The same with planes (EW_BF_CH planes of width x height: the pyramid's
 * layout) instead of interleaved pixels. */
long ew_bf_pack_image_planes(ew_device *dev, const ew_image *img, int C, float *dst);
long ew_bf_unpack_image_planes(ew_device *dev, const float *src, int C, const ew_image *img,
                               const ew_image *alpha_from);

/* Attribute packers. Non-finite attribute values become 0 and are counted
 * in *bad (may be NULL). pack_channels: the first min(view channels, stride)
 * channels into `stride` floats a pixel, zeros after (the COLOR guide:
 * stride 4; a depth: stride 1). */
void ew_bf_pack_channels(ew_device *dev, const ew_image *view, int stride, float *attr, long *bad);
/* GI: unit normal (zero stays zero), depth, sqrt(roughness) (1 without
 * roughness: diffuse). depth may be NULL (0), normal may be NULL (zero). */
void ew_bf_pack_gi(ew_device *dev, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                   float *attr, long *bad);
/* The same into planes (one per attribute channel). */
void ew_bf_pack_channels_planes(ew_device *dev, const ew_image *view, int stride, float *attr, long *bad);
void ew_bf_pack_gi_planes(ew_device *dev, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                          float *attr, long *bad);

/* The same packers as jobs, gathered in a set and run later: on given rows
 * by another pass (the pyramid's first downsampling packs the two rows it
 * is about to read, its last upsampling unpacks each row it has written:
 * ew_pyr_io), so the planes go through the cache once instead of through
 * memory twice, or on every row at once (ew_bf_io_run). planes: the
 * pyramid's layout, else interleaved pixels. A set holds up to
 * EW_BF_IO_JOBS jobs, all over views of one size; the counts of missing and
 * non-finite values are not kept (no filter op reports them). */
#define EW_BF_IO_JOBS 3
typedef struct ew_bf_io_job {
    int what, C;                 /* kind of job (bilateral.c); channels or floats a pixel */
    const ew_image *v, *v2, *v3; /* image / output and alpha_from / normal, depth, roughness */
    const float *src;            /* unpack: the planes */
    float *dst;                  /* pack: the planes */
    size_t ks, js;               /* element k of pixel j at k * ks + j * js */
    int band;                    /* unpack: src holds bands of this many rows, one a thread (0: the frame) */
    size_t band_stride;          /* floats from one thread's band to the next */
} ew_bf_io_job;
typedef struct ew_bf_io_set {
    int n;
    ew_bf_io_job job[EW_BF_IO_JOBS];
} ew_bf_io_set;
void ew_bf_io_pack_image(ew_bf_io_set *s, const ew_image *img, int C, float *dst, int planes);
void ew_bf_io_pack_channels(ew_bf_io_set *s, const ew_image *view, int stride, float *attr, int planes);
void ew_bf_io_pack_gi(ew_bf_io_set *s, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                      float *attr, int planes);
void ew_bf_io_unpack_image(ew_bf_io_set *s, const float *src, int C, const ew_image *img,
                           const ew_image *alpha_from, int planes);
/* The same as ew_bf_io_unpack_image from planes, from the pyramid's result
 * held in bands (ew_pyr_plan.band; band 0: a whole frame): the rows a call
 * runs on lie in one band, in the buffer of the thread that runs it. */
void ew_bf_io_unpack_band(ew_bf_io_set *s, const float *src, int band, long band_stride, int C, const ew_image *img,
                          const ew_image *alpha_from);
/* Run every job of the set (an ew_bf_io_set *) on rows [y0, y1) (tid: the
 * thread running it, for a banded unpack). */
void ew_bf_io_rows(void *set, int y0, int y1, int tid);
/* The pyramid's fill (ew_pyr_fill_fn): the set's packing jobs on rows
 * [y0, y1) into planes ps floats apart, pixel (x, y) at (y - row0) * width
 * + x of each: the image's EW_BF_CH planes first, the attributes' after them
 * (the jobs' own destinations are not used). */
void ew_bf_io_fill(void *set, int y0, int y1, int tid, float *planes, long ps, long row0);
/* Run every job on all rows of `any` (the views' size), on dev's threads. */
void ew_bf_io_run(ew_device *dev, ew_bf_io_set *s, const ew_image *any);

/* Brute force, rows [y0, y1) of b (b->out must not alias b->image). */
void ew_bilateral_brute_rows(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b);
/* Separable: horizontal pass into tmp, vertical pass into out. */
void ew_bilateral_separable(ew_device *dev, const ew_bf_model *m, int w, int h, const float *image,
                            const float *attr, float *tmp, float *out);

#endif
