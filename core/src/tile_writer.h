/*
 * tile_writer.h — a tiled method's cores into an output view that is also
 * the colour its tiles read where it lies (the CLI writes a denoiser's
 * result over its colour).
 *
 * Tiles go row by row (src/tiling.h). A later tile reads a core it does not
 * own only near that core's edges: the next tile of the row its last
 * `keep` columns, the next row of tiles its last `keep` rows (keep: the
 * method's halo, or what else it reads around its core). Those go out after
 * the tiles that read them, from a strip of keep columns and two buffers of
 * keep rows; the rest of a core at once. With cores at least keep across,
 * no tile reads further back.
 */
#ifndef EW_SRC_TILE_WRITER_H
#define EW_SRC_TILE_WRITER_H

#include "src/backend.h"
#include "src/tiling.h"

typedef struct ew_tile_writer {
    ew_device *dev;
    const ew_image *out; /* the output view */
    int keep;
    float *strip;        /* device: keep x the frame's height x 3 floats */
    float *pend;         /* device: 2 x the frame's width x keep x 3 floats */
    float *stage;        /* host staging for views, or NULL */
    ew_tile held;        /* where strip goes (held.cw 0: nothing held) */
} ew_tile_writer;

/* Device floats of strip and pend for a w x h frame */
size_t ew_tile_writer_floats(int w, int h, int keep);

/* Whether tiles of t may go out so: cores at least keep across. */
int ew_tile_writer_fits(const ew_tiling *t, int keep);

/* Tile t's core from src (the region's output, packed t->rw wide, 3 floats
 * a pixel; pack: device scratch of the core's size, where a rect is packed
 * before it goes out). Call for every tile in order. */
ew_result ew_tile_writer_core(ew_tile_writer *w, const ew_tiling *t, const ew_tile *tile, const float *src,
                              float *pack);

#endif
