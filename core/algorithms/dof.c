/* dof.c — CoC and domain-CoC attributes for the DoF filter. */
#include "algorithms/dof.h"

#include "src/backend.h"

static int tiles_of(int n) { return (n + EW_DOF_TILE - 1) / EW_DOF_TILE; }

size_t ew_dof_scratch_floats(int w, int h) {
    const size_t n = (size_t)w * (size_t)h, t = (size_t)tiles_of(w) * (size_t)tiles_of(h);
    return n /* coc */ + 2 * t + n * 2 /* attr */;
}

void ew_dof_args_init(ew_dof_args *a, const ew_dof_camera *cam, const float *depth, float *coc, float *tiles,
                      float *attr, int planes) {
    a->cam = *cam;
    a->tw = tiles_of(cam->width);
    a->th = tiles_of(cam->height);
    a->depth = depth;
    a->coc = coc;
    a->tiles = tiles;
    a->tiles2 = tiles + (size_t)a->tw * (size_t)a->th;
    a->attr = attr;
    a->planes = planes;
}

void ew_dof_compute_attributes(ew_device *dev, const ew_dof_camera *cam, const float *depth, float *coc,
                               float *tiles, float *attr, int planes) {
    ew_dof_args a;
    ew_dof_args_init(&a, cam, depth, coc, tiles, attr, planes);
    dev->backend->dof_attributes(dev, &a);
}

void ew_dof_attr_rows(const ew_dof_args *a, int y0, int y1, float *planes, long ps, long row0) {
    const int w = a->cam.width;
    for (int y = y0; y < y1; y++) {
        float *d = planes + (long)(y - row0) * w, *c = d + ps;
        for (int x = 0; x < w; x++) ew_dof_attr_of(x, y, a, &d[x], &c[x]);
    }
}
