#include "src/tile_writer.h"

#include "src/internal.h"

size_t ew_tile_writer_floats(int w, int h, int keep) { return (2 * (size_t)w + (size_t)h) * (size_t)keep * 3; }

int ew_tile_writer_fits(const ew_tiling *t, int keep) { return t->tw >= keep && t->th >= keep; }

/* The output view's pixels [x, x + w) x [y, y + h) from packed src */
static ew_result out_packed(ew_tile_writer *tw, const float *src, int x, int y, int w, int h) {
    if (w <= 0 || h <= 0) return EW_OK;
    const ew_image v = ew__image_crop(tw->out, x, y, w, h);
    return ew_dev_get_view(tw->dev, src, 3, &v, tw->stage);
}

ew_result ew_tile_writer_core(ew_tile_writer *tw, const ew_tiling *t, const ew_tile *tile, const float *src,
                              float *pack) {
    const int W = t->width, H = t->height, k = tw->keep;
    const int kr = tile->cx + tile->cw < W ? k : 0, kb = tile->cy + tile->ch < H ? k : 0;
    const int row = tile->cy / t->th, ox = tile->cx - tile->rx, oy = tile->cy - tile->ry;
    float *pend = tw->pend + (size_t)(row & 1) * (size_t)W * (size_t)k * 3;
    /* the columns the tile before held: this tile has read them */
    ew_result r = out_packed(tw, tw->strip, tw->held.cx, tw->held.cy, tw->held.cw, tw->held.ch);
    tw->held.cw = 0;
    /* the core but its last columns and rows */
    const int cw = tile->cw - kr, ch = tile->ch - kb;
    if (r == EW_OK && cw > 0 && ch > 0) r = ew_dev_copy_rect(tw->dev, pack, cw, 0, 0, src, tile->rw, ox, oy, cw, ch, 3);
    if (r == EW_OK) r = out_packed(tw, pack, tile->cx, tile->cy, cw, ch);
    if (r == EW_OK && kr) {
        r = ew_dev_copy_rect(tw->dev, tw->strip, kr, 0, 0, src, tile->rw, ox + cw, oy, kr, ch, 3);
        tw->held = *tile;
        tw->held.cx = tile->cx + cw;
        tw->held.cw = kr;
        tw->held.ch = ch;
    }
    if (r == EW_OK && kb) r = ew_dev_copy_rect(tw->dev, pend, W, tile->cx, 0, src, tile->rw, ox, oy + ch, tile->cw, kb, 3);
    /* the row's last tile: the last rows of the row before, which this row
     * of tiles read */
    if (r == EW_OK && !kr && row > 0)
        r = out_packed(tw, tw->pend + (size_t)((row - 1) & 1) * (size_t)W * (size_t)k * 3, 0, tile->cy - k, W, k);
    return r;
}
