/*
 * edgewise filter — edge-aware filtering of one pass of an image: the
 * pyramid filter, the exact joint bilateral filter, the separable
 * approximation or the à-trous wavelet filter, with the edge-stopping
 * functions of the pyramid paper's targets (colour, GI denoising, depth).
 * The output keeps every other layer, pass and the metadata (EXR).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "cycles_passes.h"

static const char help[] =
    "usage: edgewise filter IN -o OUT [options]\n"
    "\n"
    "Filter one pass of IN (by default the colour: Combined / Noisy Image of the\n"
    "first view layer of a Cycles multilayer EXR, or a plain EXR/PNG/TIFF image)\n"
    "with an edge-aware filter and write it to OUT. An EXR output keeps every other\n"
    "layer, pass and the metadata of IN; PNG/TIFF get the filtered pass only.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE       output file (required; not IN)\n"
    "  --method NAME           pyramid (default): the pyramid filter, cost independent of the radius\n"
    "                          bilateral: the exact joint bilateral filter (slow: radius^2 per pixel)\n"
    "                          separable: horizontal then vertical 1-D bilateral passes\n"
    "                          atrous: edge-avoiding a-trous wavelets (Dammertz et al. 2010)\n"
    "  --radius N              kernel radius in pixels, 0..256 (default 8)\n"
    "  --sigma-spatial F       domain Gaussian sigma in pixels (default radius / 3)\n"
    "  --model NAME            edge-stopping functions (pyramid, bilateral, separable):\n"
    "                          color (default): difference of the guide (the colour itself or --guide-pass)\n"
    "                          gi: GI denoising, paper Eq. 9: normal, depth, roughness passes\n"
    "                          depth: paper Eq. 10: depth pass\n"
    "                          none: a plain Gaussian\n"
    "  --sigma-range F         color: sigma of the guide difference (default 0.1)\n"
    "  --sigma-normal F        gi: exponent of (n_p . n_q) (default 32); atrous: sigma of |n_p - n_q| (0.3)\n"
    "  --sigma-depth F         gi, depth: s in exp(-s z_p |z_p - z_q|), z in scene units (default 1);\n"
    "                          atrous: sigma of the depth difference (default 0.5)\n"
    "  --sigma-luminance F     atrous: luminance sigma of the first iteration (default 0.5)\n"
    "  --iterations N          atrous: iterations (default: enough for --radius)\n"
    "  --weights W             pyramid: trained (default, built in), analytic, or a weights FILE\n"
    "  --layer NAME            view layer (default: the first with a colour pass)\n"
    "  --pass NAME             pass to filter (default: the colour); e.g. Depth with --model depth\n"
    "  --guide-pass NAME       color: guide pass (default: the filtered pass itself)\n"
    "  --normal-pass NAME      normals (default: Denoising Normal, else Normal)\n"
    "  --depth-pass NAME       depth (default: Depth, else Denoising Depth)\n"
    "  --roughness-pass NAME   gi: roughness alpha in [0,1]; without it the filter is diffuse\n"
    "  --threads N             worker threads, 0 = all cores (default 0)\n"
    "  --half | --float        EXR pixel type of written passes (default: as read)\n"
    "  --reference REF         also print PSNR/SSIM of the output against REF\n"
    "  -q, --quiet             print errors only\n"
    "  -h, --help              this text\n"
    "\n"
    "Non-finite samples (NaN, Inf) in the filtered pass are treated as missing and\n"
    "rebuilt from their neighbourhood; their count is reported.\n";

typedef struct {
    const char *in, *out, *method, *model, *weights, *layer, *pass, *guide_pass, *normal_pass, *depth_pass,
        *rough_pass, *reference;
    int radius, iterations, threads, quiet;
    float sigma_spatial, sigma_range, sigma_normal, sigma_depth, sigma_lum;
    int have_sigma_depth, have_sigma_normal;
    ewio_pixel_type type;
} options;

static const char *const methods[] = {"pyramid", "bilateral", "separable", "atrous", NULL};
static const char *const models[] = {"color", "gi", "depth", "none", NULL};

static int index_of(const char *const *names, const char *s) {
    for (int i = 0; names[i]; i++)
        if (!strcmp(names[i], s)) return i;
    return -1;
}

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->method = "pyramid";
    o->model = "color";
    o->weights = "trained";
    o->radius = 8;
    o->sigma_range = 0.1f;
    o->sigma_normal = 32.0f;
    o->sigma_depth = 1.0f;
    o->sigma_lum = 0.5f;
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
        else if (!strcmp(a, "--model")) { NEED_VALUE(); o->model = val; }
        else if (!strcmp(a, "--weights")) { NEED_VALUE(); o->weights = val; }
        else if (!strcmp(a, "--layer")) { NEED_VALUE(); o->layer = val; }
        else if (!strcmp(a, "--pass")) { NEED_VALUE(); o->pass = val; }
        else if (!strcmp(a, "--guide-pass")) { NEED_VALUE(); o->guide_pass = val; }
        else if (!strcmp(a, "--normal-pass")) { NEED_VALUE(); o->normal_pass = val; }
        else if (!strcmp(a, "--depth-pass")) { NEED_VALUE(); o->depth_pass = val; }
        else if (!strcmp(a, "--roughness-pass")) { NEED_VALUE(); o->rough_pass = val; }
        else if (!strcmp(a, "--reference")) { NEED_VALUE(); o->reference = val; }
        else if (!strcmp(a, "--radius")) { NEED_VALUE(); if (!cli_parse_int(a, val, 0, 256, &o->radius)) return 0; }
        else if (!strcmp(a, "--iterations")) { NEED_VALUE(); if (!cli_parse_int(a, val, 1, 12, &o->iterations)) return 0; }
        else if (!strcmp(a, "--threads")) { NEED_VALUE(); if (!cli_parse_int(a, val, 0, 1024, &o->threads)) return 0; }
        else if (!strcmp(a, "--sigma-spatial")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.0f, 256.0f, &o->sigma_spatial)) return 0; }
        else if (!strcmp(a, "--sigma-range")) { NEED_VALUE(); if (!cli_parse_float(a, val, 1e-4f, 1e4f, &o->sigma_range)) return 0; }
        else if (!strcmp(a, "--sigma-normal")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.0f, 1024.0f, &o->sigma_normal)) return 0; o->have_sigma_normal = 1; }
        else if (!strcmp(a, "--sigma-depth")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.0f, 1e6f, &o->sigma_depth)) return 0; o->have_sigma_depth = 1; }
        else if (!strcmp(a, "--sigma-luminance")) { NEED_VALUE(); if (!cli_parse_float(a, val, 0.0f, 1e4f, &o->sigma_lum)) return 0; }
        else if (!strcmp(a, "--half")) o->type = EWIO_HALF;
        else if (!strcmp(a, "--float")) o->type = EWIO_FLOAT;
        else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) o->quiet = 1;
        else if (a[0] == '-' && a[1] != '\0') { fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise filter --help')\n", a); return 0; }
        else if (!o->in) o->in = a;
        else { fprintf(stderr, "edgewise: unexpected argument '%s'\n", a); return 0; }
#undef NEED_VALUE
    }
    if (!o->in) { fprintf(stderr, "edgewise: filter needs an input file (see 'edgewise filter --help')\n"); return 0; }
    if (!o->out) { fprintf(stderr, "edgewise: filter needs an output file: -o OUT\n"); return 0; }
    if (index_of(methods, o->method) < 0) {
        fprintf(stderr, "edgewise: unknown --method '%s' (pyramid, bilateral, separable, atrous)\n", o->method);
        return 0;
    }
    if (index_of(models, o->model) < 0) {
        fprintf(stderr, "edgewise: unknown --model '%s' (color, gi, depth, none)\n", o->model);
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

const char *cli_pass_comps(const ewio_file *f, const char *layer, const char *pass) {
    static const char *const comps[] = {"RGBA", "RGB", "XYZ", "Z", "R", "Y", "V", NULL};
    for (int i = 0; comps[i]; i++)
        if (ewio_has_pass(f, layer, pass, comps[i])) return comps[i];
    return NULL;
}

float *cli_read_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps, char *err,
                     size_t errlen) {
    size_t n = (size_t)ewio_width(f) * (size_t)ewio_height(f) * strlen(comps);
    float *buf = (float *)malloc(n * sizeof(float));
    if (!buf) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    if (ewio_get_pass(f, layer, pass, comps, buf, err, errlen) != 0) {
        free(buf);
        return NULL;
    }
    return buf;
}

int cli_set_weights(ew_filter *flt, ew_device *dev, const char *spec, int *set_int) {
    *set_int = -1;
    if (!strcmp(spec, "trained")) { *set_int = 1; return 0; }
    if (!strcmp(spec, "analytic")) { *set_int = 0; return 0; }
    FILE *fp = fopen(spec, "rb");
    if (!fp) return cli_fail("--weights: cannot open '%s' (expected trained, analytic or a weights file)", spec);
    unsigned char *buf = NULL;
    size_t len = 0, cap = 0;
    for (;;) {
        if (len == cap) {
            cap = cap ? cap * 2 : 65536;
            unsigned char *nb = (unsigned char *)realloc(buf, cap);
            if (!nb) { free(buf); fclose(fp); return cli_fail("out of memory"); }
            buf = nb;
        }
        size_t k = fread(buf + len, 1, cap - len, fp);
        len += k;
        if (k == 0) break;
    }
    fclose(fp);
    ew_result r = ew_filter_set_data(flt, "weights", buf, len);
    free(buf);
    if (r != EW_OK) return cli_fail("--weights '%s': %s", spec, ew_device_last_error(dev));
    return 0;
}

long cli_count_nonfinite(const float *v, size_t n) {
    long k = 0;
    for (size_t i = 0; i < n; i++) k += !(v[i] - v[i] == 0.0f);
    return k;
}

/* A pass given by name must exist in the layer; NULL name = first of the
 * defaults that exists (or NULL). */
static int pick_pass(const ewio_file *f, const char *layer, const char *given, const char *const *defaults,
                     const char *what, const char **out) {
    *out = NULL;
    if (given) {
        if (!cli_pass_comps(f, layer, given))
            return cli_fail("layer '%s' has no %s pass '%s'", layer, what, given);
        *out = given;
        return 0;
    }
    for (; *defaults; defaults++)
        if (cli_pass_comps(f, layer, *defaults)) {
            *out = *defaults;
            return 0;
        }
    return 0;
}

int cmd_filter(int argc, char **argv) {
    options o;
    if (!parse(argc, argv, &o)) return EW_EXIT_USAGE;
    if (same_file(o.in, o.out))
        return cli_fail("refusing to write the output over the input '%s': choose another -o", o.in);
    if (cli_check_writable(o.out) != 0) return EW_EXIT_FAIL;
    const int method = index_of(methods, o.method), model = index_of(models, o.model);
    char err[1024];
    ewio_file *f = NULL;
    if (ewio_read(o.in, &f, err, sizeof err) != 0) return cli_fail("cannot read '%s': %s", o.in, err);
    int rc = EW_EXIT_FAIL;
    float *pix = NULL, *out = NULL, *guide = NULL, *normal = NULL, *depth = NULL, *rough = NULL;
    ew_device *dev = NULL;
    ew_filter *flt = NULL;
    const int w = ewio_width(f), h = ewio_height(f);
    const size_t n = (size_t)w * (size_t)h;

    /* the layer and the pass to filter */
    ew_layer_passes lp;
    int found = 0;
    if (o.layer) {
        found = ew_find_layer_passes(f, o.layer, &lp, err, sizeof err) == 0;
        if (!found && !o.pass) { cli_fail("%s", err); goto done; }
    } else {
        for (int i = 0; i < ewio_num_layers(f) && !found; i++)
            found = ew_find_layer_passes(f, ewio_layer_name(f, i), &lp, err, sizeof err) == 0;
    }
    const char *layer = o.layer ? o.layer : found ? lp.layer : ewio_layer_name(f, 0);
    const char *pass = o.pass ? o.pass : found ? lp.color : NULL;
    if (!pass) { cli_fail("'%s' has no colour pass to filter (%s); name one with --pass", o.in, err); goto done; }
    const char *comps = cli_pass_comps(f, layer, pass);
    if (!comps) { cli_fail("layer '%s' has no pass '%s'", layer, pass); goto done; }
    const int C = (int)strlen(comps);
    if (!(pix = cli_read_pass(f, layer, pass, comps, err, sizeof err))) { cli_fail("%s", err); goto done; }
    long bad = cli_count_nonfinite(pix, n * (size_t)C);
    if (!(out = (float *)malloc(n * (size_t)C * sizeof(float)))) { cli_fail("out of memory"); goto done; }

    /* attribute passes */
    static const char *const normals[] = {"Denoising Normal", "Normal", NULL};
    static const char *const depths[] = {"Depth", "Denoising Depth", NULL};
    static const char *const none[] = {NULL};
    const char *np = NULL, *dp = NULL, *rp = NULL, *gp = NULL;
    const int wants_features = method == 3 || model == 1 || model == 2;
    if (pick_pass(f, layer, o.normal_pass, wants_features && model != 2 ? normals : none, "normal", &np) ||
        pick_pass(f, layer, o.depth_pass, wants_features ? depths : none, "depth", &dp) ||
        pick_pass(f, layer, o.rough_pass, none, "roughness", &rp) ||
        pick_pass(f, layer, o.guide_pass, none, "guide", &gp))
        goto done;
    if (method != 3 && model == 1 && !np && !dp) {
        cli_fail("--model gi needs a normal or depth pass; layer '%s' has neither (looked for Denoising Normal, "
                 "Normal, Depth, Denoising Depth): enable them in Blender or name them with --normal-pass/--depth-pass",
                 layer);
        goto done;
    }
    if (np && !(normal = cli_read_pass(f, layer, np, "XYZ", err, sizeof err))) { cli_fail("%s", err); goto done; }
    if (dp && !(depth = cli_read_pass(f, layer, dp, cli_pass_comps(f, layer, dp), err, sizeof err))) { cli_fail("%s", err); goto done; }
    if (rp && !(rough = cli_read_pass(f, layer, rp, cli_pass_comps(f, layer, rp), err, sizeof err))) { cli_fail("%s", err); goto done; }
    const char *gcomps = gp ? cli_pass_comps(f, layer, gp) : NULL;
    if (gp && !(guide = cli_read_pass(f, layer, gp, gcomps, err, sizeof err))) { cli_fail("%s", err); goto done; }

    if (!(dev = cli_device(o.threads))) goto done;
    ew_result r = ew_filter_create(dev, o.method, &flt);
    ew_image vin = ew_image_packed(pix, w, h, C), vout = ew_image_packed(out, w, h, C);
    if (r == EW_OK) r = ew_filter_set_image(flt, "color", &vin);
    if (r == EW_OK) r = ew_filter_set_image(flt, "output", &vout);
    if (r == EW_OK && normal) {
        ew_image v = ew_image_packed(normal, w, h, 3);
        r = ew_filter_set_image(flt, "normal", &v);
    }
    if (r == EW_OK && depth) {
        /* a multi-component depth pass: its first component */
        ew_image v = ew_image_packed(depth, w, h, 1);
        v.pixel_stride = (int64_t)strlen(cli_pass_comps(f, layer, dp)) * (int64_t)sizeof(float);
        r = ew_filter_set_image(flt, "depth", &v);
    }
    if (method == 3) {
        if (r == EW_OK) r = ew_filter_set_int(flt, "radius", o.radius);
        if (r == EW_OK && o.iterations) r = ew_filter_set_int(flt, "iterations", o.iterations);
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_luminance", o.sigma_lum);
        /* atrous has its own defaults (sigmas of differences, not the gi exponent) */
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_normal", o.have_sigma_normal ? o.sigma_normal : 0.3f);
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_depth", o.have_sigma_depth ? o.sigma_depth : 0.5f);
    } else {
        if (r == EW_OK && rough) {
            ew_image v = ew_image_packed(rough, w, h, 1);
            v.pixel_stride = (int64_t)strlen(cli_pass_comps(f, layer, rp)) * (int64_t)sizeof(float);
            r = ew_filter_set_image(flt, "roughness", &v);
        }
        if (r == EW_OK && guide) {
            ew_image v = ew_image_packed(guide, w, h, (int)strlen(gcomps));
            if (v.channels > 4) v.channels = 4;
            r = ew_filter_set_image(flt, "guide", &v);
        }
        if (r == EW_OK) r = ew_filter_set_int(flt, "model", model);
        if (r == EW_OK) r = ew_filter_set_int(flt, "radius", o.radius);
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_spatial", o.sigma_spatial);
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_range", o.sigma_range);
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_normal", o.sigma_normal);
        if (r == EW_OK) r = ew_filter_set_float(flt, "sigma_depth", o.sigma_depth);
        if (r == EW_OK && method == 0) {
            int wi;
            if (cli_set_weights(flt, dev, o.weights, &wi) != 0) goto done;
            if (wi >= 0) r = ew_filter_set_int(flt, "weights", wi);
        }
    }
    double t0 = now_s();
    if (r == EW_OK) r = ew_filter_commit(flt);
    if (r == EW_OK) r = ew_filter_execute(flt);
    double dt = now_s() - t0;
    if (r != EW_OK) { cli_fail("%s filter failed: %s", o.method, ew_device_last_error(dev)); goto done; }
    if (!o.quiet) {
        fprintf(stderr, "edgewise: %s '%s' of layer '%s' (%dx%d, %s, radius %d%s%s) in %.3f s\n", o.method, pass,
                layer[0] ? layer : "(image)", w, h, method == 3 ? "luminance" : o.model, o.radius,
                normal ? ", normal" : "", depth ? ", depth" : "", dt);
        if (bad) fprintf(stderr, "edgewise: %ld non-finite samples in '%s' were treated as missing\n", bad, pass);
    }
    if (ewio_set_pass(f, layer, pass, comps, out, err, sizeof err) != 0) { cli_fail("%s", err); goto done; }
    ewio_set_attribute(f, "edgewise.version", ew_version_string());
    if (o.reference) {
        ewio_file *ref = NULL;
        if (ewio_read(o.reference, &ref, err, sizeof err) != 0) { cli_fail("cannot read reference '%s': %s", o.reference, err); goto done; }
        float *pr = cli_read_color(ref, NULL, err, sizeof err);
        if (!pr) { ewio_free(ref); cli_fail("reference '%s': %s", o.reference, err); goto done; }
        if (ewio_width(ref) != w || ewio_height(ref) != h || C < 3) {
            free(pr);
            ewio_free(ref);
            cli_fail("reference '%s' must be a %dx%d colour image to compare with the filtered colour", o.reference, w, h);
            goto done;
        }
        ew_image vr = ew_image_packed(pr, w, h, 3), vo = vout;
        vo.channels = 3;
        vo.pixel_stride = (int64_t)C * (int64_t)sizeof(float);
        double p = 0, s = 0;
        ew_image_psnr(dev, &vo, &vr, &p);
        ew_image_ssim(dev, &vo, &vr, &s);
        printf("output vs reference: PSNR %.2f dB SSIM %.4f\n", p, s);
        free(pr);
        ewio_free(ref);
    }
    if (ewio_write(f, o.out, o.type, layer, pass, err, sizeof err) != 0) {
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
    free(out);
    free(guide);
    free(normal);
    free(depth);
    free(rough);
    return rc;
}
