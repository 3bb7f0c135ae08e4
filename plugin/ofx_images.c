/*
 * Host images: fetch, check, release, and view them as the library's
 * ew_image without copying.
 *
 * OFX images are addressed bottom-up: the data pointer is the pixel at
 * (bounds.x1, bounds.y1) and row y+1 is row_bytes further (row_bytes may be
 * negative for hosts that store top-down). Renders and the library's other
 * front ends are top-down (row 0 = top), so the view starts at the top row
 * and steps by -row_bytes: the library's signed row stride covers both
 * signs without a copy.
 */
#include "ofx_plugin.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int components_of(const char *s) {
    if (!s) return 0;
    if (!strcmp(s, kOfxImageComponentRGBA)) return 4;
    if (!strcmp(s, kOfxImageComponentRGB)) return 3;
    if (!strcmp(s, kOfxImageComponentAlpha)) return 1;
    return 0;
}

OfxStatus ew_ofx_image_fetch(OfxImageClipHandle clip, OfxTime time, ew_ofx_image *img) {
    memset(img, 0, sizeof *img);
    if (!clip) return kOfxStatErrBadHandle;
    OfxPropertySetHandle h = NULL;
    OfxStatus st = ew_ofx.effect->clipGetImage(clip, time, NULL, &h);
    if (st != kOfxStatOK) return st;
    if (!h) return kOfxStatFailed;
    img->handle = h; /* from here on the caller releases it, whatever happens */

    const OfxPropertySuiteV1 *P = ew_ofx.prop;
    char *depth = NULL, *comps = NULL;
    void *data = NULL;
    int b[4] = {0, 0, 0, 0}, row_bytes = 0;
    if (P->propGetString(h, kOfxImageEffectPropPixelDepth, 0, &depth) != kOfxStatOK ||
        P->propGetString(h, kOfxImageEffectPropComponents, 0, &comps) != kOfxStatOK ||
        P->propGetPointer(h, kOfxImagePropData, 0, &data) != kOfxStatOK ||
        P->propGetIntN(h, kOfxImagePropBounds, 4, b) != kOfxStatOK ||
        P->propGetInt(h, kOfxImagePropRowBytes, 0, &row_bytes) != kOfxStatOK) {
        snprintf(img->problem, sizeof img->problem,
                 "lacks one of pixel depth, components, data, bounds and row bytes");
        return kOfxStatErrBadHandle;
    }
    img->comps = components_of(comps);
    if (!depth || strcmp(depth, kOfxBitDepthFloat) != 0) {
        snprintf(img->problem, sizeof img->problem, "is %s, not 32-bit float", depth ? depth : "of no pixel depth");
        return kOfxStatErrImageFormat;
    }
    if (img->comps == 0) {
        snprintf(img->problem, sizeof img->problem, "has components %s, not RGBA, RGB or Alpha",
                 comps ? comps : "(none)");
        return kOfxStatErrImageFormat;
    }

    img->bounds.x1 = b[0];
    img->bounds.y1 = b[1];
    img->bounds.x2 = b[2];
    img->bounds.y2 = b[3];
    int64_t w = (int64_t)b[2] - b[0], h64 = (int64_t)b[3] - b[1];
    int64_t row = w * img->comps * (int64_t)sizeof(float);
    int64_t rb = row_bytes < 0 ? -(int64_t)row_bytes : (int64_t)row_bytes;
    /* An image whose layout does not hold the format it claims (a host
     * that labels 8-bit pixels float after clip preferences asked for
     * float, as the OpenFX SDK's hostDemo does) is refused before a pixel
     * is read: reading it would run past the host's buffer. */
    if (w < 0 || h64 < 0 || w > 65536 || h64 > 65536) {
        snprintf(img->problem, sizeof img->problem, "has bounds (%d, %d, %d, %d): inverted or over 65536 pixels",
                 b[0], b[1], b[2], b[3]);
        return kOfxStatErrImageFormat;
    }
    if (w > 0 && h64 > 0 && !data) {
        snprintf(img->problem, sizeof img->problem, "has no pixel data");
        return kOfxStatErrImageFormat;
    }
    if (w > 0 && h64 > 0 && rb < row) {
        snprintf(img->problem, sizeof img->problem,
                 "has rows of %d bytes, fewer than the %lld its %lld pixels of %d-channel float take",
                 row_bytes, (long long)row, (long long)w, img->comps);
        return kOfxStatErrImageFormat;
    }
    img->data = (char *)data;
    img->row_bytes = row_bytes;
    return kOfxStatOK;
}

int ew_ofx_clip_unmapped_components(OfxImageClipHandle clip) {
    OfxPropertySetHandle props = NULL;
    char *comps = NULL;
    if (!clip || ew_ofx.effect->clipGetPropertySet(clip, &props) != kOfxStatOK || !props) return 0;
    if (ew_ofx.prop->propGetString(props, kOfxImageClipPropUnmappedComponents, 0, &comps) != kOfxStatOK) return 0;
    return components_of(comps);
}

void ew_ofx_image_release(ew_ofx_image *img) {
    if (img->handle) ew_ofx.effect->clipReleaseImage(img->handle);
    memset(img, 0, sizeof *img);
}

float *ew_ofx_image_pixel(const ew_ofx_image *img, int x, int y) {
    return (float *)(img->data + (int64_t)(y - img->bounds.y1) * img->row_bytes +
                     (int64_t)(x - img->bounds.x1) * img->comps * (int64_t)sizeof(float));
}

ew_image ew_ofx_image_view(const ew_ofx_image *img, int first, int channels) {
    ew_image v;
    memset(&v, 0, sizeof v);
    v.width = img->bounds.x2 - img->bounds.x1;
    v.height = img->bounds.y2 - img->bounds.y1;
    v.channels = channels;
    v.format = EW_FORMAT_FLOAT;
    v.pixel_stride = (int64_t)img->comps * (int64_t)sizeof(float);
    v.row_stride = -(int64_t)img->row_bytes;
    v.data = ew_ofx_image_pixel(img, img->bounds.x1, img->bounds.y2 - 1) + first;
    return v;
}
