/*
 * edgewise dof — depth of field on a sharp render from its depth pass and
 * the values of a Blender camera (the library's "dof" filter: thin-lens CoC,
 * then the pyramid filter with the paper's DoF functions).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "cycles_passes.h"

static const char help[] =
    "usage: edgewise dof IN -o OUT --focus-distance M [options]\n"
    "\n"
    "Add depth of field to a sharp (pinhole) render. IN needs a colour pass and a\n"
    "depth pass: a Cycles multilayer EXR with Depth (planar camera depth in metres;\n"
    "Blender: View Layer > Passes > Data > Z). The camera values are the ones of a\n"
    "Blender camera. A blurred background stays behind a sharp foreground, and a\n"
    "blurred foreground spreads over a sharp background. An EXR output keeps every\n"
    "other layer, pass and the metadata of IN; PNG/TIFF get the colour only.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE       output file (required; not IN)\n"
    "  --focus-distance M      distance in focus in metres (Blender: Focus Distance; default 10)\n"
    "  --fstop F               f-number (Blender: F-Stop; default 2.8)\n"
    "  --focal-length MM       focal length in mm (Blender: Focal Length; default 50)\n"
    "  --sensor-width MM       sensor size in mm, applied to the larger image side\n"
    "                          (Blender: Sensor Fit Auto, Size; default 36)\n"
    "  --radius N              largest kernel radius in pixels, 1..128 (default 32)\n"
    "  --blur-scale F          the filter's CoC per pixel of the lens's CoC (default 2.12:\n"
    "                          a real lens's blur size; see docs/filters.md)\n"
    "  --method NAME           pyramid (default, fast), bilateral (exact, slow), separable\n"
    "  --weights W             pyramid: trained (default, built in), analytic, or a weights FILE\n"
    "  --layer NAME            view layer (default: the first with a colour pass)\n"
    "  --depth-pass NAME       depth pass (default: Depth, else Denoising Depth)\n"
    "  --coc-pass NAME         also write the signed circle of confusion in pixels as this\n"
    "                          pass (EXR; negative in front of the focus plane)\n"
    "  --threads N             worker threads, 0 = all cores (default 0)\n"
    "  --half | --float        EXR pixel type of written passes (default: as read)\n"
    "  --reference REF         also print PSNR/SSIM of the output against REF (e.g. a\n"
    "                          Cycles render with depth of field)\n"
    "  -q, --quiet             print errors only\n"
    "  -h, --help              this text\n";

typedef struct {
    const char *in, *out, *method, *weights, *layer, *depth_pass, *coc_pass, *reference;
    float focus, fstop, focal, sensor, blur_scale;
    int radius, threads, quiet;
    ewio_pixel_type type;
} options;

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->method = "pyramid";
    o->weights = "trained";
    o->focus = 10.0f;
    o->fstop = 2.8f;
    o->focal = 50.0f;
    o->sensor = 36.0f;
    o->radius = 32;
    o->blur_scale = 2.1213203f;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *val = i + 1 < argc ? argv[i + 1] : NULL;
#define NEED_VALUE()                                                              \
    do {                                                                          \
        if (!val) { fprintf(stderr, "edgewise: %s needs a value\n", a); return 0; } \
        i++;                                                                      \
    } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(help, stdout); exit(0); }
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED_VALUE(); o->out = val; }
        else if (!strcmp(a, "--method")) { NEED_VALUE(); o->method = val; }
        else if (!strcmp(a, "--weights")) { NEED_VALUE(); o->weights = val; }
        else if (!strcmp(a, "--layer")) { NEED_VALUE(); o->layer = val; }
        else if (!strcmp(a, "--depth-pass")) { NEED_VALUE(); o->depth_pass = val; }
        else if (!strcmp(a, "--coc-pass")) { NEED_VALUE(); o->coc_pass = val; }
        else if (!strcmp(a, "--reference")) { NEED_VALUE(); o->reference = val; }
        else if (!strcmp(a, "--focus-distance")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.01f, 1e6f, &o->focus)) return 0; }
        else if (!strcmp(a, "--fstop")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.1f, 1024.0f, &o->fstop)) return 0; }
        else if (!strcmp(a, "--focal-length")) { NEED_VALUE(); if (!cli_parse_float(a, val, 1.0f, 5000.0f, &o->focal)) return 0; }
        else if (!strcmp(a, "--sensor-width")) { NEED_VALUE(); if (!cli_parse_float(a, val, 1.0f, 1000.0f, &o->sensor)) return 0; }
        else if (!strcmp(a, "--radius")) { NEED_VALUE(); if (!cli_parse_int(a, val, 1, 128, &o->radius)) return 0; }
        else if (!strcmp(a, "--blur-scale")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.1f, 10.0f, &o->blur_scale)) return 0; }
        else if (!strcmp(a, "--threads")) { NEED_VALUE(); if (!cli_parse_int(a, val, 0, 1024, &o->threads)) return 0; }
        else if (!strcmp(a, "--half")) o->type = EWIO_HALF;
        else if (!strcmp(a, "--float")) o->type = EWIO_FLOAT;
        else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) o->quiet = 1;
        else if (a[0] == '-' && a[1] != '\0') { fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise dof --help')\n", a); return 0; }
        else if (!o->in) o->in = a;
        else { fprintf(stderr, "edgewise: unexpected argument '%s'\n", a); return 0; }
#undef NEED_VALUE
    }
    if (!o->in) { fprintf(stderr, "edgewise: dof needs an input file (see 'edgewise dof --help')\n"); return 0; }
    if (!o->out) { fprintf(stderr, "edgewise: dof needs an output file: -o OUT\n"); return 0; }
    if (strcmp(o->method, "pyramid") && strcmp(o->method, "bilateral") && strcmp(o->method, "separable")) {
        fprintf(stderr, "edgewise: unknown --method '%s' (pyramid, bilateral, separable)\n", o->method);
        return 0;
    }
    if (o->focus * 1000.0f <= o->focal) {
        fprintf(stderr, "edgewise: --focus-distance %g m must be beyond the focal length (%g mm)\n", (double)o->focus,
                (double)o->focal);
        return 0;
    }
    return 1;
}

static int same_file(const char *a, const char *b) {
    struct stat sa, sb;
    if (stat(a, &sa) == 0 && stat(b, &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    return strcmp(a, b) == 0;
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int cmd_dof(int argc, char **argv) {
    options o;
    if (!parse(argc, argv, &o)) return EW_EXIT_USAGE;
    if (same_file(o.in, o.out))
        return cli_fail("refusing to write the output over the input '%s': choose another -o", o.in);
    if (cli_check_writable(o.out) != 0) return EW_EXIT_FAIL;
    char err[1024];
    ewio_file *f = NULL;
    if (ewio_read(o.in, &f, err, sizeof err) != 0) return cli_fail("cannot read '%s': %s", o.in, err);
    int rc = EW_EXIT_FAIL;
    float *pix = NULL, *depth = NULL, *out = NULL, *coc = NULL;
    ew_device *dev = NULL;
    ew_filter *flt = NULL;
    const int w = ewio_width(f), h = ewio_height(f);
    const size_t n = (size_t)w * (size_t)h;
    ew_layer_passes lp;
    int found = 0;
    if (o.layer) {
        found = ew_find_layer_passes(f, o.layer, &lp, err, sizeof err) == 0;
    } else {
        for (int i = 0; i < ewio_num_layers(f) && !found; i++)
            found = ew_find_layer_passes(f, ewio_layer_name(f, i), &lp, err, sizeof err) == 0;
    }
    if (!found) { cli_fail("%s", err); goto done; }
    const char *layer = lp.layer;
    const char *dp = o.depth_pass;
    if (dp && !cli_pass_comps(f, layer, dp)) { cli_fail("layer '%s' has no depth pass '%s'", layer, dp); goto done; }
    if (!dp) dp = cli_pass_comps(f, layer, "Depth") ? "Depth" : cli_pass_comps(f, layer, "Denoising Depth") ? "Denoising Depth" : NULL;
    if (!dp) {
        cli_fail("layer '%s' of '%s' has no depth pass (looked for Depth and Denoising Depth): enable the Z pass in "
                 "Blender (View Layer > Passes > Data) or name one with --depth-pass", layer[0] ? layer : "(image)", o.in);
        goto done;
    }
    const char *comps = lp.color_comps, *dcomps = cli_pass_comps(f, layer, dp);
    const int C = (int)strlen(comps);
    if (!(pix = cli_read_pass(f, layer, lp.color, comps, err, sizeof err)) ||
        !(depth = cli_read_pass(f, layer, dp, dcomps, err, sizeof err))) {
        cli_fail("%s", err);
        goto done;
    }
    long bad = cli_count_nonfinite(pix, n * (size_t)C);
    if (!(out = (float *)malloc(n * (size_t)C * sizeof(float))) || !(coc = (float *)malloc(n * sizeof(float)))) {
        cli_fail("out of memory");
        goto done;
    }
    if (!(dev = cli_device(o.threads))) goto done;
    ew_result r = ew_filter_create(dev, "dof", &flt);
    ew_image vin = ew_image_packed(pix, w, h, C), vout = ew_image_packed(out, w, h, C);
    ew_image vd = ew_image_packed(depth, w, h, 1), vc = ew_image_packed(coc, w, h, 1);
    vd.pixel_stride = (int64_t)strlen(dcomps) * (int64_t)sizeof(float);
    if (r == EW_OK) r = ew_filter_set_image(flt, "color", &vin);
    if (r == EW_OK) r = ew_filter_set_image(flt, "depth", &vd);
    if (r == EW_OK) r = ew_filter_set_image(flt, "coc", &vc);
    if (r == EW_OK) r = ew_filter_set_image(flt, "output", &vout);
    if (r == EW_OK) r = ew_filter_set_float(flt, "focus_distance", o.focus);
    if (r == EW_OK) r = ew_filter_set_float(flt, "fstop", o.fstop);
    if (r == EW_OK) r = ew_filter_set_float(flt, "focal_length", o.focal);
    if (r == EW_OK) r = ew_filter_set_float(flt, "sensor_width", o.sensor);
    if (r == EW_OK) r = ew_filter_set_int(flt, "radius", o.radius);
    if (r == EW_OK) r = ew_filter_set_float(flt, "blur_scale", o.blur_scale);
    if (r == EW_OK) r = ew_filter_set_int(flt, "method", !strcmp(o.method, "pyramid") ? 0 : !strcmp(o.method, "bilateral") ? 1 : 2);
    if (r == EW_OK && !strcmp(o.method, "pyramid")) {
        int wi;
        if (cli_set_weights(flt, dev, o.weights, &wi) != 0) goto done;
        if (wi >= 0) r = ew_filter_set_int(flt, "weights", wi);
    }
    double t0 = now_s();
    if (r == EW_OK) r = ew_filter_commit(flt);
    if (r == EW_OK) r = ew_filter_execute(flt);
    double dt = now_s() - t0;
    if (r != EW_OK) { cli_fail("depth of field failed: %s", ew_device_last_error(dev)); goto done; }
    if (!o.quiet) {
        float cmin = 0, cmax = 0;
        for (size_t i = 0; i < n; i++) {
            cmin = coc[i] < cmin ? coc[i] : cmin;
            cmax = coc[i] > cmax ? coc[i] : cmax;
        }
        fprintf(stderr,
                "edgewise: dof (%s) of layer '%s' %dx%d: f = %g mm, f/%g, focus %g m, sensor %g mm; CoC from %.1f px "
                "(near) to %.1f px (far) in %.3f s\n",
                o.method, layer[0] ? layer : "(image)", w, h, (double)o.focal, (double)o.fstop, (double)o.focus,
                (double)o.sensor, (double)cmin, (double)cmax, dt);
        if (bad) fprintf(stderr, "edgewise: %ld non-finite samples in '%s' were treated as missing\n", bad, lp.color);
    }
    if (ewio_set_pass(f, layer, lp.color, comps, out, err, sizeof err) != 0 ||
        (o.coc_pass && ewio_set_pass(f, layer, o.coc_pass, "Z", coc, err, sizeof err) != 0)) {
        cli_fail("%s", err);
        goto done;
    }
    ewio_set_attribute(f, "edgewise.version", ew_version_string());
    if (o.reference) {
        ewio_file *ref = NULL;
        if (ewio_read(o.reference, &ref, err, sizeof err) != 0) { cli_fail("cannot read reference '%s': %s", o.reference, err); goto done; }
        float *pr = cli_read_color(ref, NULL, err, sizeof err);
        if (!pr || ewio_width(ref) != w || ewio_height(ref) != h || C < 3) {
            free(pr);
            ewio_free(ref);
            cli_fail("reference '%s' must be a %dx%d colour image", o.reference, w, h);
            goto done;
        }
        ew_image vr = ew_image_packed(pr, w, h, 3), vo = vout, vi = vin;
        vo.channels = vi.channels = 3;
        vo.pixel_stride = vi.pixel_stride = (int64_t)C * (int64_t)sizeof(float);
        double p0 = 0, p1 = 0, s0 = 0, s1 = 0;
        ew_image_psnr(dev, &vi, &vr, &p0);
        ew_image_psnr(dev, &vo, &vr, &p1);
        ew_image_ssim(dev, &vi, &vr, &s0);
        ew_image_ssim(dev, &vo, &vr, &s1);
        printf("vs reference: sharp input PSNR %.2f dB SSIM %.4f -> with depth of field PSNR %.2f dB SSIM %.4f\n", p0,
               s0, p1, s1);
        free(pr);
        ewio_free(ref);
    }
    if (ewio_write(f, o.out, o.type, layer, lp.color, err, sizeof err) != 0) {
        cli_fail("cannot write '%s': %s", o.out, err);
        goto done;
    }
    if (!o.quiet) fprintf(stderr, "edgewise: wrote %s\n", o.out);
    rc = 0;
done:
    ew_filter_destroy(flt);
    ew_device_destroy(dev);
    ewio_free(f);
    free(pix);
    free(depth);
    free(out);
    free(coc);
    return rc;
}
