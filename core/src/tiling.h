/*
 * tiling.h — a frame split into tiles under a memory budget, for methods
 * whose scratch grows with the frame (kpcn, nbg).
 *
 * Each tile's core (what it outputs) is computed on a region that adds
 * `halo` pixels on every side, clipped to the frame; only the core is kept.
 * When the halo covers everything a core pixel's output reads, and the
 * region's origin sits on the method's grid (`align`: kpcn's poolings,
 * nbg's bilateral grid cells), every core pixel sees what it sees in one
 * whole-frame pass and the output is the same bits. The method supplies the
 * halo, the alignment and what one region costs.
 */
#ifndef EW_SRC_TILING_H
#define EW_SRC_TILING_H

#include <stddef.h>

#define EW_TILE_MIN 8 /* smallest core side: below it the halo is nearly all the work */

typedef struct ew_tiling {
    int width, height; /* the frame */
    int tw, th;        /* core size of every tile but the last of a row / column (multiples of align) */
    int halo, align;
    int nx, ny;
    int rw, rh;        /* the largest region */
} ew_tiling;

typedef struct ew_tile {
    int cx, cy, cw, ch; /* core: what the tile outputs */
    int rx, ry, rw, rh; /* region: what it computes */
} ew_tile;

/* Device floats one rw x rh region needs. */
typedef size_t (*ew_region_floats_fn)(const void *ctx, int rw, int rh);

/* Tiles of a w x h frame whose regions each need at most budget_floats
 * (region_floats); fewest region pixels in all. One tile when the whole
 * frame fits; tiles of EW_TILE_MIN when even those exceed the budget.
 * halo must be a multiple of align (>= 1). */
void ew_tiling_plan(int w, int h, int halo, int align, size_t budget_floats, ew_region_floats_fn region_floats,
                    const void *ctx, ew_tiling *t);
void ew_tile_at(const ew_tiling *t, int i, ew_tile *tile); /* i in [0, nx * ny) */

#endif
