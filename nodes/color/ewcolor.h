/*
 * ewcolor.h — C interface to the OpenColorIO shim (ewcolor.cpp), the only
 * place that talks to OpenColorIO.
 *
 * The config is chosen once per call, in this order:
 *   1. $OCIO when set and non-empty (as every OCIO application does);
 *   2. Blender's own config (Debian's blender-data package), so previews
 *      match what Blender shows;
 *   3. OpenColorIO's built-in "ocio://default" (OCIO >= 2.2 only; Debian 12
 *      ships 2.1, which does not have it);
 *   4. a minimal config built here: colour spaces "Linear" (scene_linear),
 *      "Raw" (data) and "sRGB", display "sRGB" with views "Standard" and
 *      "Raw".
 * Every function returning int returns 0 on success and non-zero with a
 * one-line message in err. No exception escapes.
 */
#ifndef EDGEWISE_EWCOLOR_H
#define EDGEWISE_EWCOLOR_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ewcolor_proc ewcolor_proc;

/* Which config is in use, e.g. "Blender: /usr/share/blender/.../config.ocio". */
void ewcolor_config_name(char *buf, size_t len);

/* A colour-space conversion `from` -> `to` (names or roles such as
 * "scene_linear"). */
int ewcolor_transform(const char *from, const char *to, ewcolor_proc **out, char *err, size_t errlen);

/* A display/view transform as Blender's colour management does it: scene
 * linear values (colour space `from`, "" = scene_linear) times
 * 2^exposure, the view transform of `display`/`view` ("" = the config's
 * default display, and that display's default view) with `look` ("" = the
 * view's own), then display values to the power 1/gamma. */
int ewcolor_display(const char *from, const char *display, const char *view, const char *look, float exposure,
                    float gamma, ewcolor_proc **out, char *err, size_t errlen);

/* The names ewcolor_display takes for "" display / view: the config's
 * default display and that display's default view ("" on failure). */
void ewcolor_default_view(const char *display, char *display_out, size_t dlen, char *view_out, size_t vlen);

/* Apply to packed float pixels in place; channels is 3 (RGB) or 4 (RGBA,
 * alpha passed through; colour associated with it, as in EXR: transformed
 * as colour / alpha, then multiplied by alpha again). */
void ewcolor_apply(const ewcolor_proc *p, float *pixels, int width, int height, int channels);
void ewcolor_free(ewcolor_proc *p); /* NULL is a no-op */

#ifdef __cplusplus
}
#endif

#endif
