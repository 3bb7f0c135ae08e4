/*
 * edgewise denoise — denoise every view layer (or one) of a render and write
 * the result atomically, keeping every other layer, pass and the metadata.
 */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "cycles_passes.h"
#include "method_run.h"

static const char help[] =
    "usage: edgewise denoise IN -o OUT [options]\n"
    "\n"
    "Denoise a render. IN is a Cycles multilayer EXR (every view layer with a\n"
    "Combined or Noisy Image pass is denoised; feature passes Denoising Albedo/\n"
    "Normal/Depth are used when present) or a plain EXR/PNG/TIFF colour image.\n"
    "OUT's extension picks the format. An EXR output keeps every layer, pass and\n"
    "the header metadata of IN: Combined holds the denoised colour and the noisy\n"
    "original is kept as the pass 'Noisy Image' (as Blender does). PNG/TIFF get\n"
    "the denoised colour of the first layer only. OUT is written atomically and\n"
    "must not be IN.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE     output file (required)\n"
    "  --layer NAME          denoise only this view layer\n"
    "  --method NAME         auto (default): no more model than the frame needs, by its sample\n"
    "                        count (the file's Cycles metadata; --samples overrides it) or a\n"
    "                        noise estimate, and its passes: nbg 2layer-3grid-1spp at 1-2 spp,\n"
    "                        nbg 2layer-3grid at 3-8 spp, a bilateral grid as fine as the frame\n"
    "                        allows above that or without albedo/normal/depth (docs/nbg.md)\n"
    "                        nbg: neural bilateral grid, guides learned by a small CNN (needs\n"
    "                        albedo, normal and depth)\n"
    "                        bgrid: bilateral grid guided by albedo/normal/depth (needs albedo)\n"
    "                        bgrid-color: bilateral grid guided by the colour alone\n"
    "  --model NAME|PATH     nbg's weights (implies --method nbg): a built-in model,\n"
    "                        2layer-3grid (default; real time, trained on 1-64 spp),\n"
    "                        2layer-3grid-1spp (trained on 1 spp), 2layer-1grid (fastest) or\n"
    "                        7layer-3grid (offline), or a weights file written by train_nbg\n"
    "                        (models/nbg/README.md)\n"
    "  --threads N           worker threads, 0 = all cores (default 0)\n"
    "  --half | --float      EXR pixel type of the written passes (default: as read)\n"
    "  --reference REF       also print PSNR/SSIM of input and output against REF\n"
    "  -q, --quiet           print errors only\n"
    "  -h, --help            this text\n"
    "\n"
    "method parameters (--name-with-dashes VALUE):\n"
    "%s"
    "\n"
    "Non-finite colour samples (NaN, Inf from half overflow) are treated as missing\n"
    "and rebuilt from their neighbourhood; negative samples count as black.\n";

#define MAX_SET (EW_RUN_MAX_PARAMS - 1) /* method parameters; one more slot is nbg's "model" */

typedef struct {
    const char *in, *out, *layer, *method, *reference;
    const char *model;    /* --model: a built-in name or a weights file (issue 3) */
    int model_index;      /* the built-in's "model" parameter, or -1 for a file */
    void *model_bytes;    /* the file's bytes */
    size_t model_size;
    int threads, quiet;
    ewio_pixel_type type;
    int num_set; /* method parameters given on the command line */
    char set_name[MAX_SET][64];
    float set_value[MAX_SET];
} options;

/* The parameter of any denoiser called `name` (NULL if none). */
static int find_param(const char *name, ew_param_info *info) {
    for (int32_t i = 0; i < ew_method_count("denoiser"); i++) {
        const char *m;
        int32_t np;
        ew_method_get("denoiser", i, &m, NULL, NULL, &np);
        for (int32_t k = 0; k < np; k++)
            if (ew_method_param("denoiser", m, k, info) == EW_OK && !strcmp(info->name, name)) return 1;
    }
    return 0;
}

static void print_help(void) {
    char params[4096];
    size_t used = 0;
    params[0] = '\0';
    for (int32_t i = 0; i < ew_method_count("denoiser"); i++) {
        const char *m;
        int32_t np;
        ew_method_get("denoiser", i, &m, NULL, NULL, &np);
        for (int32_t k = 0; k < np && used < sizeof params; k++) {
            ew_param_info p;
            ew_method_param("denoiser", m, k, &p);
            if (!strcmp(p.name, "model")) continue; /* nbg's: --model NAME|PATH, listed above */
            char opt[64];
            snprintf(opt, sizeof opt, "--%s", p.name);
            for (char *c = opt; *c; c++)
                if (*c == '_') *c = '-';
            int n = snprintf(params + used, sizeof params - used, "  %-20s  %s (%s, %g..%g, default %g)\n", opt, p.hint, m,
                             (double)p.min_value, (double)p.max_value, (double)p.default_value);
            if (n < 0) break;
            used += (size_t)n;
        }
    }
    printf(help, params);
}

/* nbg's built-in models, by its "model" parameter (README.md, docs/nbg.md) */
static const char *const builtin[] = {"2layer-3grid", "2layer-1grid", "7layer-3grid", "2layer-3grid-1spp"};
#define NUM_BUILTIN 4

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->method = "auto";
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *val = i + 1 < argc ? argv[i + 1] : NULL;
#define NEED_VALUE()                                                              \
    do {                                                                          \
        if (!val) { fprintf(stderr, "edgewise: %s needs a value\n", a); return 0; } \
        i++;                                                                      \
    } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { print_help(); exit(0); }
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED_VALUE(); o->out = val; }
        else if (!strcmp(a, "--layer")) { NEED_VALUE(); o->layer = val; }
        else if (!strcmp(a, "--method")) { NEED_VALUE(); o->method = val; }
        else if (!strcmp(a, "--model")) { NEED_VALUE(); o->model = val; }
        else if (!strcmp(a, "--reference")) { NEED_VALUE(); o->reference = val; }
        else if (!strcmp(a, "--threads")) { NEED_VALUE(); if (!cli_parse_int(a, val, 0, 1024, &o->threads)) return 0; }
        else if (!strcmp(a, "--half")) o->type = EWIO_HALF;
        else if (!strcmp(a, "--float")) o->type = EWIO_FLOAT;
        else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) o->quiet = 1;
        else if (a[0] == '-' && a[1] == '-' && strlen(a) < 64) {
            char name[64];
            ew_param_info p;
            snprintf(name, sizeof name, "%s", a + 2);
            for (char *c = name; *c; c++)
                if (*c == '-') *c = '_';
            if (!find_param(name, &p)) {
                fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise denoise --help')\n", a);
                return 0;
            }
            if (o->num_set == MAX_SET) {
                fprintf(stderr, "edgewise: at most %d method parameters\n", MAX_SET);
                return 0;
            }
            NEED_VALUE();
            if (!cli_parse_float(a, val, p.min_value, p.max_value, &o->set_value[o->num_set])) return 0;
            snprintf(o->set_name[o->num_set++], sizeof o->set_name[0], "%s", name);
        }
        else if (a[0] == '-' && a[1] != '\0') { fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise denoise --help')\n", a); return 0; }
        else if (!o->in) o->in = a;
        else { fprintf(stderr, "edgewise: unexpected argument '%s'\n", a); return 0; }
#undef NEED_VALUE
    }
    if (!o->in) { fprintf(stderr, "edgewise: denoise needs an input file (see 'edgewise denoise --help')\n"); return 0; }
    if (!o->out) { fprintf(stderr, "edgewise: denoise needs an output file: -o OUT\n"); return 0; }
    if (strcmp(o->method, "auto") && strcmp(o->method, "nbg") && strcmp(o->method, "bgrid") &&
        strcmp(o->method, "bgrid-color")) {
        fprintf(stderr, "edgewise: unknown method '%s' (auto, nbg, bgrid, bgrid-color)\n", o->method);
        return 0;
    }
    if (o->model && strcmp(o->method, "auto") && strcmp(o->method, "nbg")) {
        fprintf(stderr, "edgewise: --model is for --method nbg, not '%s'\n", o->method);
        return 0;
    }
    if (o->model) o->method = "nbg"; /* a model names the method */
    /* --model: a built-in model's name, else a weights file (read later) */
    o->model_index = 0;
    for (int k = 0; o->model && k < NUM_BUILTIN; k++)
        if (!strcmp(o->model, builtin[k])) o->model_index = k;
    if (o->model && strcmp(o->model, builtin[o->model_index]) != 0) o->model_index = -1;
    return 1;
}

/* The bytes of a weights file for --model PATH (its validation is the
 * library's, at ew_denoiser_set_data). */
static int read_model(options *o) {
    FILE *f = fopen(o->model, "rb");
    if (!f) return cli_fail("cannot read model '%s': %s (built-in models: 2layer-3grid, 2layer-1grid, 7layer-3grid)",
                            o->model, strerror(errno));
    long n = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    if (n <= 0 || n > (1L << 28) || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return cli_fail("cannot read model '%s': not a weights file (size %ld)", o->model, n);
    }
    o->model_bytes = malloc((size_t)n);
    o->model_size = (size_t)n;
    int bad = !o->model_bytes || fread(o->model_bytes, 1, (size_t)n, f) != (size_t)n;
    fclose(f);
    if (bad) return cli_fail("cannot read model '%s'", o->model);
    return 0;
}

/* Same file, by inode when both exist, else by resolved path. */
static int same_file(const char *a, const char *b) {
    struct stat sa, sb;
    if (stat(a, &sa) == 0 && stat(b, &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    return strcmp(a, b) == 0;
}

typedef struct {
    ewio_file *f;
    ew_device *dev;
    const options *o;
    float *out;
    char err[1024];
} job;

/* What runs on a layer: the library method and its settings (bench and the
 * stability suite run the same ew_method_run, so their figures are what
 * this command gives). */
static void make_spec(const job *j, const char *method, ew_method_spec *spec) {
    memset(spec, 0, sizeof *spec);
    spec->label = method;
    spec->kind = "denoiser";
    spec->name = !strcmp(method, "bgrid-color") ? "bgrid" : method;
    if (!strcmp(method, "nbg")) {
        if (j->o->model_index >= 0) {
            spec->param_names[spec->num_params] = "model";
            spec->param_values[spec->num_params++] = (float)j->o->model_index;
        } else {
            spec->data_name = "weights";
            spec->data = j->o->model_bytes;
            spec->data_size = j->o->model_size;
        }
    }
    for (int k = 0; k < j->o->num_set; k++) { /* MAX_SET leaves room for "model" */
        spec->param_names[spec->num_params] = j->o->set_name[k];
        spec->param_values[spec->num_params++] = j->o->set_value[k];
    }
}

/* Denoise one layer in memory and put the result back into the file. */
static int denoise_layer(job *j, const ew_layer_passes *lp) {
    const int w = ewio_width(j->f), h = ewio_height(j->f);
    const char *layer = lp->layer;
    char layers[512];
    ew_list_layers(j->f, layers, sizeof layers);
    const char *method = j->o->method;
    if (!strcmp(method, "nbg") && (!lp->albedo || !lp->normal || !lp->depth))
        return cli_fail("layer '%s' lacks the %s pass that --method nbg needs (it reads Denoising Albedo, Normal "
                        "and Depth); layers found: %s. Enable Denoising Data in Blender's view layer passes, or "
                        "use --method auto",
                        layer, !lp->albedo ? "albedo" : !lp->normal ? "normal" : "depth", layers);
    if (!strcmp(method, "bgrid") && !lp->albedo)
        return cli_fail("layer '%s' has no albedo pass (looked for 'Denoising Albedo' and 'DiffCol'), which "
                        "--method bgrid needs; layers found: %s. Enable Denoising Data in Blender's view layer "
                        "passes, or use --method bgrid-color",
                        layer, layers);

    int nc = (int)strlen(lp->color_comps);
    float *orig = (float *)malloc((size_t)w * h * nc * sizeof(float));
    if (!orig) return cli_fail("out of memory");
    if (ewio_get_pass(j->f, layer, lp->color, lp->color_comps, orig, j->err, sizeof j->err) != 0) {
        free(orig);
        return cli_fail("%s", j->err);
    }
    ew_layer_data in;
    if (ew_layer_data_read(j->f, lp, &in, j->err, sizeof j->err) != 0) {
        free(orig);
        return cli_fail("%s", j->err);
    }
    if (!strcmp(method, "bgrid-color")) { /* guided by the colour alone */
        free(in.albedo);
        free(in.normal);
        free(in.depth);
        in.albedo = in.normal = in.depth = NULL;
    }
    ew_method_spec spec;
    char chosen[200] = "";
    make_spec(j, method, &spec);
    spec.chosen = chosen;
    spec.chosen_len = sizeof chosen;
    double ms = 0.0;
    int bad = ew_method_run(j->dev, &spec, &in, j->out, &ms, j->err, sizeof j->err);
    const int guided = in.albedo != NULL;
    const int has_nd = in.normal && in.depth, has_n = in.normal != NULL, has_d = in.depth != NULL;
    ew_layer_data_free(&in);
    if (bad) {
        free(orig);
        return cli_fail("denoising layer '%s' failed: %s", layer, j->err);
    }
    if (!strcmp(method, "nbg") && j->o->model_index < 0) /* the weights file's path */
        snprintf(chosen, sizeof chosen, "nbg %s", j->o->model);
    /* Keep the noisy original beside the result, as Blender does. */
    int put = 0;
    if (strcmp(lp->color, "Noisy Image") != 0 && lp->layer[0] != '\0')
        put = ewio_set_pass(j->f, layer, "Noisy Image", lp->color_comps, orig, j->err, sizeof j->err);
    const char *dst = lp->layer[0] != '\0' ? "Combined" : lp->color;
    if (put == 0) put = ewio_set_pass(j->f, layer, dst, "RGB", j->out, j->err, sizeof j->err);
    free(orig);
    if (put != 0) return cli_fail("%s", j->err);
    if (!j->o->quiet)
        fprintf(stderr, "edgewise: layer '%s': %s (%s%s%s) %dx%d in %.3f s\n", layer[0] ? layer : "(image)", chosen,
                lp->color, guided ? " guided by albedo" : "",
                guided ? (has_nd ? ", normal, depth" : has_n ? ", normal" : has_d ? ", depth" : "") : "", w, h,
                ms * 1e-3);
    return 0;
}

static int print_quality(job *j, const ew_layer_passes *lp, const float *noisy_rgb) {
    char err[512];
    ewio_file *ref = NULL;
    if (ewio_read(j->o->reference, &ref, err, sizeof err) != 0)
        return cli_fail("reference: %s", err);
    float *pr = cli_read_color(ref, NULL, err, sizeof err);
    int rc = 0;
    if (!pr) {
        rc = cli_fail("reference '%s': %s", j->o->reference, err);
    } else if (ewio_width(ref) != ewio_width(j->f) || ewio_height(ref) != ewio_height(j->f)) {
        rc = cli_fail("reference is %dx%d but the input is %dx%d", ewio_width(ref), ewio_height(ref),
                      ewio_width(j->f), ewio_height(j->f));
    } else {
        const int w = ewio_width(j->f), h = ewio_height(j->f);
        ew_image vr = ew_image_packed(pr, w, h, 3);
        ew_image vn = ew_image_packed((float *)noisy_rgb, w, h, 3);
        ew_image vo = ew_image_packed(j->out, w, h, 3);
        double pn, po, sn, so;
        ew_image_psnr(j->dev, &vn, &vr, &pn);
        ew_image_psnr(j->dev, &vo, &vr, &po);
        ew_image_ssim(j->dev, &vn, &vr, &sn);
        ew_image_ssim(j->dev, &vo, &vr, &so);
        printf("layer '%s' vs reference: input PSNR %.2f dB SSIM %.4f -> output PSNR %.2f dB SSIM %.4f (%+.2f dB)\n",
               lp->layer, pn, sn, po, so, po - pn);
    }
    free(pr);
    ewio_free(ref);
    return rc;
}

int cmd_denoise(int argc, char **argv) {
    options o;
    if (!parse(argc, argv, &o)) return EW_EXIT_USAGE;
    if (o.model && o.model_index < 0 && read_model(&o) != 0) return EW_EXIT_FAIL;
    if (same_file(o.in, o.out))
        return cli_fail("refusing to write the output over the input '%s': choose another -o", o.in);

    if (cli_check_writable(o.out) != 0) return EW_EXIT_FAIL;
    job j;
    memset(&j, 0, sizeof j);
    j.o = &o;
    if (ewio_read(o.in, &j.f, j.err, sizeof j.err) != 0) return cli_fail("%s", j.err);
    int rc = EW_EXIT_FAIL;
    const size_t n = (size_t)ewio_width(j.f) * (size_t)ewio_height(j.f);
    float *noisy_first = NULL;
    j.out = (float *)malloc(n * 3 * sizeof(float));
    noisy_first = (float *)malloc(n * 3 * sizeof(float));
    if (!j.out || !noisy_first) {
        cli_fail("out of memory for a %dx%d image", ewio_width(j.f), ewio_height(j.f));
        goto done;
    }
    if (!(j.dev = cli_device(o.threads))) goto done;

    int done_layers = 0;
    ew_layer_passes first;
    const int num_layers = ewio_num_layers(j.f); /* before any pass is added */
    for (int i = 0; i < num_layers; i++) {
        char layer[256];
        snprintf(layer, sizeof layer, "%s", ewio_layer_name(j.f, i));
        if (o.layer && strcmp(o.layer, layer) != 0) continue;
        ew_layer_passes lp;
        if (ew_find_layer_passes(j.f, layer, &lp, j.err, sizeof j.err) != 0) {
            if (o.layer) { cli_fail("%s", j.err); goto done; }
            continue; /* a layer without colour (e.g. only data passes) is left alone */
        }
        if (done_layers == 0) {
            first = lp;
            if (ewio_get_pass(j.f, layer, lp.color, "RGB", noisy_first, j.err, sizeof j.err) != 0) {
                cli_fail("%s", j.err);
                goto done;
            }
        }
        if (denoise_layer(&j, &lp) != 0) goto done;
        if (done_layers == 0 && o.reference && print_quality(&j, &first, noisy_first) != 0) goto done;
        done_layers++;
    }
    if (done_layers == 0) {
        char layers[512];
        ew_list_layers(j.f, layers, sizeof layers);
        if (o.layer) cli_fail("no layer '%s' in '%s' (layers found: %s)", o.layer, o.in, layers);
        else cli_fail("'%s' has no colour pass to denoise (layers found: %s)", o.in, layers);
        goto done;
    }
    ewio_set_attribute(j.f, "edgewise.version", ew_version_string());
    /* PNG/TIFF take only one pass: the first denoised layer's colour */
    const char *wpass = first.layer[0] ? "Combined" : first.color;
    if (ewio_write(j.f, o.out, o.type, first.layer, wpass, j.err, sizeof j.err) != 0) {
        cli_fail("%s", j.err);
        goto done;
    }
    if (!o.quiet) fprintf(stderr, "edgewise: wrote %s\n", o.out);
    rc = 0;
done:
    ew_device_destroy(j.dev);
    ewio_free(j.f);
    free(j.out);
    free(noisy_first);
    free(o.model_bytes);
    return rc;
}
