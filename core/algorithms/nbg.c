#include "algorithms/nbg.h"

#include <string.h>

#include "algorithms/bgrid.h"

#include "src/backend.h"
#include "src/internal.h"

int ew_nbg_band_rows(const ew_guidenet *net, int height) {
    /* 64 output rows keep the 2-layer net's halo (2 rows a side a layer) at
     * ~6% extra work on its expensive first layer; the 7-layer net's halo
     * is 3.5x larger, so its bands are twice as tall. */
    int b = net->nlayers <= 2 ? 64 : 128;
    return height < b ? height : b;
}

size_t ew_nbg_band_floats(const ew_guidenet *net, int width, int band_rows) {
    return ew_gn_planes_floats(width, band_rows + 4 * net->nlayers, net->nfeat);
}

size_t ew_nbg_device_floats(const ew_guidenet *net, int width, int height, size_t *grid_floats, size_t *band_floats) {
    size_t grid = 0;
    for (int g = 0; g < net->ngrids; g++) {
        ew_bgrid_params gp;
        if (!ew_bgrid_params_init(&gp, width, height, net->rate_s[g], net->rate_d[g], 3)) return 0;
        if (ew_bgrid_floats(&gp) > grid) grid = ew_bgrid_floats(&gp);
    }
    const size_t n = (size_t)width * (size_t)height;
    const size_t band = ew_nbg_band_floats(net, width, ew_nbg_band_rows(net, height));
    if (grid_floats) *grid_floats = grid;
    if (band_floats) *band_floats = band;
    return net->nparams + n * (3 * 3 + 1 + 3 * 4) + n * (size_t)net->nout + band + grid;
}

int ew_nbg_align(const ew_guidenet *net) {
    int a = 1;
    for (int g = 0; g < net->ngrids; g++) {
        const float r = net->rate_s[g];
        const int ri = (int)r;
        if ((float)ri != r || ri < 1 || (ri & (ri - 1))) return 0;
        if (ri > a) a = ri;
    }
    return a;
}

int ew_nbg_halo(const ew_guidenet *net) {
    const int align = ew_nbg_align(net);
    if (!align) return 0;
    const int inputs = 2 * net->nlayers > 2 ? 2 * net->nlayers : 2;
    const int halo = 2 * align + 1 + inputs;
    return (halo + align - 1) / align * align;
}

size_t ew_nbg_region_floats(const ew_guidenet *net, int rw, int rh, int tiled) {
    size_t grid = 0;
    for (int g = 0; g < net->ngrids; g++) {
        ew_bgrid_params gp;
        if (!ew_bgrid_params_init(&gp, rw, rh, net->rate_s[g], net->rate_d[g], 3)) return 0;
        if (ew_bgrid_floats(&gp) > grid) grid = ew_bgrid_floats(&gp);
    }
    const size_t n = (size_t)rw * (size_t)rh;
    const size_t per_px = 3 * 4 + (size_t)net->nout + (tiled ? 1 : 0);
    return n * per_px + ew_nbg_band_floats(net, rw, ew_nbg_band_rows(net, rh)) + grid;
}

static int imax(int a, int b) { return a > b ? a : b; }
static int imin(int a, int b) { return a < b ? a : b; }

ew_result ew_nbg_guidenet_forward(ew_device *dev, const ew_nbg_forward *f, int (*progress)(void *, double),
                                  void *user) {
    const ew_guidenet *net = f->net;
    const int L = net->nlayers, W = f->width, H = f->height, B = f->band_rows;
    const int halo = 2 * L; /* input rows needed beyond a band, each side */
    ew_gn_planes band;
    ew_gn_planes_layout(&band, f->band_mem, W, B + 2 * halo, net->nfeat);
    const size_t band_bytes = ew_nbg_band_floats(net, W, B) * sizeof(float);
    ew_result r = dev->backend->mem_zero(dev, f->band_mem, band_bytes);
    if (r != EW_OK) return r;
    for (int y0 = 0; y0 < H; y0 += B) {
        const int y1 = imin(y0 + B, H);
        const int top = y0 - halo; /* image row of band row 0 */
        /* Rows outside the image must read as zero (SAME padding); a band
         * at the top or bottom may hold rows of the previous band there. */
        if (y0 > 0 && y1 + halo > H) {
            r = dev->backend->mem_zero(dev, f->band_mem, band_bytes);
            if (r != EW_OK) return r;
        }
        ew_gn_input_args in;
        in.width = W;
        in.y0 = imax(0, top);
        in.y1 = imin(H, y1 + halo);
        in.color = f->color;
        in.albedo = f->albedo;
        in.normal = f->normal;
        in.depth = f->depth;
        in.in_stride = f->in_stride;
        in.depth_scale = f->depth_scale;
        in.dst = ew_gn_plane_row(&band, 0, in.y0 - top);
        in.rs = band.rs;
        in.ps = band.ps;
        dev->backend->gn_input(dev, &in);
        for (int l = 0; l < L; l++) {
            const int reach = 2 * (L - 1 - l); /* rows of this layer's output the rest needs */
            const int a = imax(0, y0 - reach), b = imin(H, y1 + reach);
            ew_conv_args ca;
            ew_guidenet_layer_args(net, l, f->params, &band, a - top, b - a, f->outputs + (long)a * W, W,
                                   (long)W * H, &ca);
            dev->backend->conv5(dev, &ca);
        }
        if (progress && !progress(user, (double)y1 / H)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    return EW_OK;
}

/* ---- built-in models (nbg_weights_data.c, generated from models/nbg/) ---- */
extern const unsigned char ew_nbg_weights_2layer_3grid[], ew_nbg_weights_2layer_1grid[], ew_nbg_weights_7layer_3grid[],
    ew_nbg_weights_2layer_3grid_1spp[];
extern const size_t ew_nbg_weights_2layer_3grid_size, ew_nbg_weights_2layer_1grid_size,
    ew_nbg_weights_7layer_3grid_size, ew_nbg_weights_2layer_3grid_1spp_size;

const char *const ew_nbg_model_names[EW_NBG_NUM_MODELS + 1] = {"2layer-3grid", "2layer-1grid", "7layer-3grid",
                                                                "2layer-3grid-1spp", NULL};

const char *ew_nbg_model_name(int model) {
    return model >= 0 && model < EW_NBG_NUM_MODELS ? ew_nbg_model_names[model] : NULL;
}

void ew_nbg_builtin_weights(int model, const unsigned char **bytes, size_t *size) {
    switch (model) {
    case 0: *bytes = ew_nbg_weights_2layer_3grid; *size = ew_nbg_weights_2layer_3grid_size; break;
    case 1: *bytes = ew_nbg_weights_2layer_1grid; *size = ew_nbg_weights_2layer_1grid_size; break;
    case 2: *bytes = ew_nbg_weights_7layer_3grid; *size = ew_nbg_weights_7layer_3grid_size; break;
    case 3: *bytes = ew_nbg_weights_2layer_3grid_1spp; *size = ew_nbg_weights_2layer_3grid_1spp_size; break;
    default: *bytes = NULL; *size = 0; break;
    }
}
