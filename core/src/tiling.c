#include "src/tiling.h"

#include <string.h>

#include "kernels/compat.h"

/* Core size n split into tiles of side t: the regions' summed length along
 * that axis. */
static long regions_length(int n, int t, int halo) {
    long sum = 0;
    for (int c = 0; c < n; c += t) {
        const int r0 = c - halo < 0 ? 0 : c - halo;
        const int r1 = c + t + halo > n ? n : c + t + halo;
        sum += r1 - r0;
    }
    return sum;
}

static int region_side(int n, int t, int halo) {
    if (t >= n) return n;
    const int r = t + 2 * halo;
    return r > n ? n : r;
}

void ew_tiling_plan(int w, int h, int halo, int align, size_t budget_floats, ew_region_floats_fn region_floats,
                    const void *ctx, ew_tiling *t) {
    memset(t, 0, sizeof *t);
    t->width = w;
    t->height = h;
    t->tw = w;
    t->th = h;
    t->halo = halo;
    const int A = t->align = align;
    if (region_floats(ctx, w, h) > budget_floats) {
        /* for each tile width, the tallest tile that fits; keep the plan
         * with the fewest region pixels (the work, halos included) */
        double best = -1.0;
        int last = 0;
        for (int nx = 1; nx <= (w + EW_TILE_MIN - 1) / EW_TILE_MIN; nx++) {
            const int tw = ((w + nx - 1) / nx + A - 1) / A * A;
            if (tw == last || tw < EW_TILE_MIN) continue;
            last = tw;
            const int rw = region_side(w, tw, halo);
            int lo = 0, hi = (h + A - 1) / A; /* th = A * k: the largest k whose region fits */
            while (lo < hi) {
                const int mid = (lo + hi + 1) / 2;
                if (region_floats(ctx, rw, region_side(h, A * mid, halo)) <= budget_floats)
                    lo = mid;
                else
                    hi = mid - 1;
            }
            if (A * lo < EW_TILE_MIN) continue;
            const double cost = (double)regions_length(w, tw, halo) * (double)regions_length(h, A * lo, halo);
            if (best < 0.0 || cost < best) {
                best = cost;
                t->tw = tw;
                t->th = A * lo;
            }
        }
        if (best < 0.0) t->tw = t->th = (EW_TILE_MIN + A - 1) / A * A;
        if (t->tw > w) t->tw = w;
        if (t->th > h) t->th = h;
    }
    t->nx = (w + t->tw - 1) / t->tw;
    t->ny = (h + t->th - 1) / t->th;
    t->rw = region_side(w, t->tw, halo);
    t->rh = region_side(h, t->th, halo);
}

void ew_tile_at(const ew_tiling *t, int i, ew_tile *tile) {
    const int ix = i % t->nx, iy = i / t->nx;
    tile->cx = ix * t->tw;
    tile->cy = iy * t->th;
    tile->cw = ew_mini(t->tw, t->width - tile->cx);
    tile->ch = ew_mini(t->th, t->height - tile->cy);
    tile->rx = ew_maxi(tile->cx - t->halo, 0);
    tile->ry = ew_maxi(tile->cy - t->halo, 0);
    tile->rw = ew_mini(tile->cx + tile->cw + t->halo, t->width) - tile->rx;
    tile->rh = ew_mini(tile->cy + tile->ch + t->halo, t->height) - tile->ry;
}
