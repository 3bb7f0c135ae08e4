/*
 * edgewise denoise — denoise every view layer (or one) of a render and write
 * the result atomically, keeping every other layer, pass and the metadata.
 */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "cycles_passes.h"
#include "method_run.h"

static const char intro[] =
    "usage: edgewise denoise IN -o OUT [options]\n"
    "\n"
    "Denoise a render. IN is a Cycles multilayer EXR (every view layer with a\n"
    "Combined or Noisy Image pass is denoised; feature passes Denoising Albedo/\n"
    "Normal/Depth are used when present) or a plain EXR/PNG/TIFF/JPEG colour image.\n"
    "OUT's extension picks the format. An EXR output keeps every layer, pass and\n"
    "the header metadata of IN: Combined holds the denoised colour and the noisy\n"
    "original is kept as the pass 'Noisy Image' (as Blender does). PNG/TIFF/JPEG\n"
    "get the denoised colour of the first layer only. OUT is written atomically\n"
    "and must not be IN.\n"
    "\n"
    "PNG and JPEG are 8-bit display images: the linear colour goes through\n"
    "OpenColorIO's display/view transform first, as the graph's `display` node\n"
    "does (config: $OCIO, else Blender's, else a built-in sRGB), so the file\n"
    "looks as the render does in Blender. An 8-bit input (PNG, JPEG) is already\n"
    "display-encoded and is written as it is. TIFF and EXR keep linear floats.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE     output file (required)\n"
    "  --layer NAME          denoise only this view layer\n"
    "  --method NAME         the library's denoiser (default: the first listed below)\n"
    "  --threads N           worker threads, 0 = all cores (default 0)\n"
    "  --half | --float      EXR pixel type of the written passes (default: as read)\n"
    "  --reference REF       also print PSNR/SSIM of input and output against REF\n"
    "  --display NAME        PNG/JPEG output: OpenColorIO display (default: the config's)\n"
    "  --view NAME           PNG/JPEG output: view transform (default: the display's, e.g. Standard)\n"
    "  --raw                 PNG/JPEG output: linear values clipped to 0..1, no display transform\n"
    "  -q, --quiet           print errors only (and no progress bar, shown on a terminal)\n"
    "  -h, --help            this text\n";

static const char outro[] =
    "\n"
    "A parameter only one denoiser has picks it when --method is not given (e.g.\n"
    "--model runs nbg). Non-finite colour samples (NaN, Inf from half overflow)\n"
    "are treated as missing and rebuilt from their neighbourhood; negative samples\n"
    "count as black.\n";

/* Command-line presets: a library method run on fewer of the layer's
 * passes, or refusing to run without one (rather than falling back to a
 * guide the user did not ask for). Methods themselves come from the
 * library. */
static const struct {
    const char *name, *method;
    int features;      /* 0: the layer's albedo, normal and depth are not given to it */
    const char *needs; /* a feature pass the preset will not run without */
    const char *summary;
} presets[] = {
    {"bgrid", "bgrid", 1, "albedo", NULL},
    {"bgrid-color", "bgrid", 0, NULL, "bilateral grid guided by the colour alone"},
};
#define NUM_PRESETS ((int)(sizeof presets / sizeof presets[0]))

#define MAX_SET (EW_RUN_MAX_PARAMS - 1)
#define MAX_OPTS 96

typedef struct {
    const char *in, *out, *layer, *method, *reference;
    int method_given;
    int threads, quiet;
    ewio_pixel_type type;
    cli_view view; /* --display, --view, --raw */
    int num_set; /* method parameters given on the command line */
    const char *set_name[MAX_SET]; /* the library's static names */
    const char *set_text[MAX_SET];
    /* resolved for the method */
    float set_value[MAX_SET];
    const char *data_name; /* a parameter given as a file (set_data) */
    const char *data_path;
    void *data_bytes;
    size_t data_size;
} options;

/* Every denoiser's parameters, once each, as getopt_long options. */
typedef struct {
    char option[MAX_OPTS][64];
    const char *param[MAX_OPTS];
    int n;
    struct option longs[MAX_OPTS + 16];
} param_options;

enum { OPT_LAYER = 1000, OPT_METHOD, OPT_THREADS, OPT_HALF, OPT_FLOAT, OPT_REFERENCE, OPT_DISPLAY, OPT_VIEW, OPT_RAW,
       OPT_PARAM = 2000 };

static void build_options(param_options *po) {
    memset(po, 0, sizeof *po);
    for (int32_t i = 0; i < ew_method_count("denoiser"); i++) {
        const char *m = NULL;
        int32_t np = 0;
        ew_method_get("denoiser", i, &m, NULL, NULL, &np);
        for (int32_t k = 0; k < np && po->n < MAX_OPTS; k++) {
            ew_param_info p;
            if (ew_method_param("denoiser", m, k, &p) != EW_OK) continue;
            int dup = 0;
            for (int q = 0; q < po->n; q++) dup |= !strcmp(po->param[q], p.name);
            if (dup) continue;
            po->param[po->n] = p.name;
            cli_option_name(p.name, "", po->option[po->n], sizeof po->option[0]);
            po->n++;
        }
    }
    static const struct option fixed[] = {
        {"output", required_argument, NULL, 'o'},        {"quiet", no_argument, NULL, 'q'},
        {"help", no_argument, NULL, 'h'},                {"layer", required_argument, NULL, OPT_LAYER},
        {"method", required_argument, NULL, OPT_METHOD}, {"threads", required_argument, NULL, OPT_THREADS},
        {"half", no_argument, NULL, OPT_HALF},           {"float", no_argument, NULL, OPT_FLOAT},
        {"reference", required_argument, NULL, OPT_REFERENCE},
        {"display", required_argument, NULL, OPT_DISPLAY}, {"view", required_argument, NULL, OPT_VIEW},
        {"raw", no_argument, NULL, OPT_RAW},
    };
    int n = 0;
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) po->longs[n++] = fixed[i];
    for (int i = 0; i < po->n; i++) po->longs[n++] = (struct option){po->option[i], required_argument, NULL, OPT_PARAM + i};
    po->longs[n] = (struct option){NULL, 0, NULL, 0};
}

static int32_t param_index(const char *method, const char *name) {
    ew_param_info p;
    for (int32_t k = 0; ew_method_param("denoiser", method, k, &p) == EW_OK; k++)
        if (!strcmp(p.name, name)) return k;
    return -1;
}

static void print_help(void) {
    fputs(intro, stdout);
    for (int32_t i = 0; i < ew_method_count("denoiser"); i++) {
        const char *m = NULL, *summary = NULL;
        int32_t np = 0;
        ew_method_get("denoiser", i, &m, &summary, NULL, &np);
        printf("\n--method %s: %s\n", m, summary ? summary : "");
        for (int k = 0; k < NUM_PRESETS; k++)
            if (!strcmp(presets[k].method, m) && presets[k].summary)
                printf("--method %s: %s\n", presets[k].name, presets[k].summary);
        for (int32_t k = 0; k < np; k++) cli_print_param_help("denoiser", m, k);
    }
    fputs(outro, stdout);
}

/* The library method a --method name runs (a preset's, or itself). */
static const char *library_method(const char *name) {
    for (int k = 0; k < NUM_PRESETS; k++)
        if (!strcmp(presets[k].name, name)) return presets[k].method;
    return name;
}

/* Whether the method behind --method `name` has an input image `image`. */
static int method_takes(const char *name, const char *image) {
    ew_image_info im;
    for (int32_t k = 0; ew_method_image(NULL, library_method(name), k, &im) == EW_OK; k++)
        if (!strcmp(im.name, image)) return 1;
    return 0;
}

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    param_options *po = (param_options *)malloc(sizeof *po);
    if (!po) return 0;
    build_options(po);
    const char *first = NULL;
    ew_method_get("denoiser", 0, &first, NULL, NULL, NULL);
    o->method = first ? first : "";
    opterr = 0;
    optind = 1;
    int c, ok = 1;
    while (ok && (c = getopt_long(argc, argv, ":o:qh", po->longs, NULL)) != -1) {
        const char *a = argv[optind - 1];
        switch (c) {
        case 'o': o->out = optarg; break;
        case 'q': o->quiet = 1; break;
        case 'h': print_help(); free(po); exit(0);
        case OPT_LAYER: o->layer = optarg; break;
        case OPT_METHOD: o->method = optarg; o->method_given = 1; break;
        case OPT_THREADS: ok = cli_parse_int("--threads", optarg, 0, 1024, &o->threads); break;
        case OPT_HALF: o->type = EWIO_HALF; break;
        case OPT_FLOAT: o->type = EWIO_FLOAT; break;
        case OPT_REFERENCE: o->reference = optarg; break;
        case OPT_DISPLAY: o->view.display = optarg; break;
        case OPT_VIEW: o->view.view = optarg; break;
        case OPT_RAW: o->view.raw = 1; break;
        case ':': fprintf(stderr, "edgewise: %s needs a value\n", a); ok = 0; break;
        case '?': fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise denoise --help')\n", a); ok = 0; break;
        default:
            if (c >= OPT_PARAM && c < OPT_PARAM + po->n) {
                if (o->num_set == MAX_SET) {
                    fprintf(stderr, "edgewise: at most %d method parameters\n", MAX_SET);
                    ok = 0;
                    break;
                }
                o->set_name[o->num_set] = po->param[c - OPT_PARAM];
                o->set_text[o->num_set++] = optarg;
            }
            break;
        }
    }
    free(po);
    if (!ok) return 0;
    for (int i = optind; i < argc; i++) {
        if (!o->in) o->in = argv[i];
        else { fprintf(stderr, "edgewise: unexpected argument '%s'\n", argv[i]); return 0; }
    }
    if (!o->in) { fprintf(stderr, "edgewise: denoise needs an input file (see 'edgewise denoise --help')\n"); return 0; }
    if (!o->out) { fprintf(stderr, "edgewise: denoise needs an output file: -o OUT\n"); return 0; }
    /* without --method, a parameter of another denoiser picks it: the one
     * whose enum names the value (--model 2layer-1grid is nbg's), else the
     * first in the library's order (--model FILE stays nbg, as the help says;
     * kpcn weights need --method kpcn) */
    for (int i = 0; i < o->num_set && !o->method_given; i++) {
        if (param_index(library_method(o->method), o->set_name[i]) >= 0) continue;
        const char *first_m = NULL, *named = NULL;
        for (int32_t k = 0; k < ew_method_count("denoiser"); k++) {
            const char *m = NULL;
            ew_method_get("denoiser", k, &m, NULL, NULL, NULL);
            int32_t pi = param_index(m, o->set_name[i]);
            if (pi < 0) continue;
            if (!first_m) first_m = m;
            if (!named && ew_method_param_choice_index("denoiser", m, pi, o->set_text[i]) >= 0) named = m;
        }
        if (named) o->method = named;
        else if (first_m) o->method = first_m;
    }
    const char *lm = library_method(o->method);
    const char *kind = ew_method_kind(lm);
    if (!kind || strcmp(kind, "denoiser") != 0) {
        char names[512];
        size_t used = 0;
        names[0] = '\0';
        for (int32_t k = 0; k < ew_method_count("denoiser") && used < sizeof names; k++) {
            const char *m = NULL;
            ew_method_get("denoiser", k, &m, NULL, NULL, NULL);
            int n = snprintf(names + used, sizeof names - used, "%s%s", k ? ", " : "", m);
            if (n > 0) used += (size_t)n;
        }
        for (int k = 0; k < NUM_PRESETS && used < sizeof names; k++) {
            if (ew_method_kind(presets[k].name)) continue; /* a preset named like its method */
            int n = snprintf(names + used, sizeof names - used, ", %s", presets[k].name);
            if (n > 0) used += (size_t)n;
        }
        fprintf(stderr, "edgewise: unknown method '%s' (%s)\n", o->method, names);
        return 0;
    }
    /* the values, checked against the method's own descriptor */
    for (int i = 0; i < o->num_set; i++) {
        char name[60], opt[64];
        cli_option_name(o->set_name[i], "", name, sizeof name);
        snprintf(opt, sizeof opt, "--%s", name);
        int32_t k = param_index(lm, o->set_name[i]);
        if (k < 0) {
            fprintf(stderr, "edgewise: denoiser '%s' has no parameter %s (see 'edgewise denoise --help')\n", lm, opt);
            return 0;
        }
        ew_param_info p;
        ew_method_param("denoiser", lm, k, &p);
        int32_t nc = ew_method_param_num_choices("denoiser", lm, k);
        const char *data = ew_method_param_data("denoiser", lm, k);
        if (nc > 0) {
            int32_t choice = ew_method_param_choice_index("denoiser", lm, k, o->set_text[i]);
            if (choice >= 0) {
                o->set_value[i] = (float)choice;
            } else if (data) { /* a file instead of a built-in choice: read in cmd_denoise */
                o->data_name = data;
                o->data_path = o->set_text[i];
                o->set_name[i] = NULL;
            } else {
                fprintf(stderr, "edgewise: unknown %s '%s'\n", opt, o->set_text[i]);
                return 0;
            }
        } else if (!cli_parse_float(opt, o->set_text[i], p.min_value, p.max_value, &o->set_value[i])) {
            return 0;
        }
    }
    return 1;
}

/* The bytes of a file given for a data parameter (its validation is the
 * library's, at set_data). */
static int read_data(options *o) {
    const char *why = "";
    FILE *f = cli_fopen_regular(o->data_path, &why); /* a FIFO would block, a device never end */
    if (!f) return cli_fail("cannot read '%s': %s (see 'edgewise denoise --help' for the built-in names)",
                            o->data_path, why);
    long n = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    if (n <= 0 || n > (1L << 28) || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return cli_fail("cannot read '%s': not a weights file (size %ld)", o->data_path, n);
    }
    o->data_bytes = malloc((size_t)n);
    o->data_size = (size_t)n;
    int bad = !o->data_bytes || fread(o->data_bytes, 1, (size_t)n, f) != (size_t)n;
    fclose(f);
    if (bad) return cli_fail("cannot read '%s'", o->data_path);
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
    /* buffers lent to the file (ewio_lend_pass): freed after the write */
    float **lent;
    int nlent;
    char err[1024];
} job;

/* Lend buf to the file as the pass (it is written from there), or copy it
 * when the job cannot keep it. 0 on success. */
static int put_result(job *j, const char *layer, const char *pass, const char *comps, float *buf) {
    float **l = (float **)realloc(j->lent, (size_t)(j->nlent + 1) * sizeof *l);
    if (!l) return ewio_set_pass(j->f, layer, pass, comps, buf, j->err, sizeof j->err);
    j->lent = l;
    if (ewio_lend_pass(j->f, layer, pass, comps, buf, j->err, sizeof j->err) != 0) return 1;
    j->lent[j->nlent++] = buf;
    return 0;
}

static void free_lent(job *j) {
    for (int k = 0; k < j->nlent; k++) ew_host_free(j->lent[k]);
    free(j->lent);
    j->lent = NULL;
    j->nlent = 0;
}

/* What runs on a layer: the library method and its settings (bench and the
 * stability suite run the same ew_method_run, so their figures are what
 * this command gives). */
static void make_spec(const job *j, const char *method, ew_method_spec *spec) {
    memset(spec, 0, sizeof *spec);
    spec->label = method;
    spec->kind = "denoiser";
    spec->name = library_method(method);
    for (int k = 0; k < j->o->num_set; k++) {
        if (!j->o->set_name[k]) continue; /* given as data */
        spec->param_names[spec->num_params] = j->o->set_name[k];
        spec->param_values[spec->num_params++] = j->o->set_value[k];
    }
    if (j->o->data_name) {
        spec->data_name = j->o->data_name;
        spec->data = j->o->data_bytes;
        spec->data_size = j->o->data_size;
    }
}

/* Denoise one layer in memory and put the result back into the file. */

/* A pass the CLI holds a copy of while the method runs. */
typedef struct {
    const char *pass, *comps;
    const float *data;
} feature_passes;

/* The feature passes of lp copied into in (albedo, normal, depth, the
 * motion vectors' XY), at most 4. */
static int layer_features(const ew_layer_passes *lp, const ew_layer_data *in, feature_passes fp[4]) {
    int n = 0;
    if (in->albedo) fp[n++] = (feature_passes){lp->albedo, "RGB", in->albedo};
    if (in->normal) fp[n++] = (feature_passes){lp->normal, "XYZ", in->normal};
    if (in->depth) fp[n++] = (feature_passes){lp->depth, "Z", in->depth};
    if (in->vector) fp[n++] = (feature_passes){"Vector", "XY", in->vector};
    return n;
}

static int denoise_layer(job *j, const ew_layer_passes *lp) {
    const int w = ewio_width(j->f), h = ewio_height(j->f);
    const char *layer = lp->layer;
    char layers[512];
    ew_list_layers(j->f, layers, sizeof layers);
    const char *method = j->o->method, *lm = library_method(method);
    /* the images the method cannot run without, from its descriptor */
    ew_image_info im;
    for (int32_t k = 0; ew_method_image("denoiser", lm, k, &im) == EW_OK; k++) {
        if (!im.required || !strcmp(im.name, "color") || !strcmp(im.name, "output")) continue;
        const char *have = !strcmp(im.name, "albedo") ? lp->albedo : !strcmp(im.name, "normal") ? lp->normal
                           : !strcmp(im.name, "depth") ? lp->depth : NULL;
        if (!have)
            return cli_fail("layer '%s' lacks the %s pass that --method %s needs (it reads Denoising Albedo, Normal "
                            "and Depth); layers found: %s. Enable Denoising Data in Blender's view layer passes, or "
                            "use --method auto",
                            layer, im.name, lm, layers);
    }
    for (int k = 0; k < NUM_PRESETS; k++) {
        if (strcmp(presets[k].name, method) != 0 || !presets[k].needs) continue;
        if (!strcmp(presets[k].needs, "albedo") && !lp->albedo) {
            const char *without = NULL;
            for (int q = 0; q < NUM_PRESETS; q++)
                if (!strcmp(presets[q].method, presets[k].method) && !presets[q].features) without = presets[q].name;
            return cli_fail("layer '%s' has no albedo pass (looked for 'Denoising Albedo' and 'DiffCol'), which "
                            "--method %s needs; layers found: %s. Enable Denoising Data in Blender's view layer "
                            "passes%s%s",
                            layer, method, layers, without ? ", or use --method " : "", without ? without : "");
        }
    }

    const double t_read = cli_seconds();
    /* The noisy original goes beside the result, as Blender keeps it: from
     * the input file at write time when the file still holds it there (a
     * scanline EXR), else from a copy taken now. */
    const int keep_noisy = strcmp(lp->color, "Noisy Image") != 0 && lp->layer[0] != '\0';
    const int noisy_in_file = ewio_pass_in_source(j->f, layer, lp->color, lp->color_comps);
    int nc = (int)strlen(lp->color_comps);
    float *orig = NULL;
    if (keep_noisy && !noisy_in_file) {
        if (!(orig = (float *)ew_host_alloc((size_t)w * h * nc * sizeof(float)))) return cli_fail("out of memory");
        if (ewio_get_pass(j->f, layer, lp->color, lp->color_comps, orig, j->err, sizeof j->err) != 0) {
            ew_host_free(orig);
            return cli_fail("%s", j->err);
        }
    }
    ew_layer_data in;
    if (ew_layer_data_read(j->f, lp, &in, j->err, sizeof j->err) != 0) {
        ew_host_free(orig);
        return cli_fail("%s", j->err);
    }
    /* the colour is in in.color now (and in orig or the input file for the
     * noisy pass), and the result goes back over it: the file need not hold
     * it too while the method works */
    const char *dst = lp->layer[0] != '\0' ? "Combined" : lp->color;
    if (!strcmp(dst, lp->color)) ewio_release_pass(j->f, layer, lp->color, "RGB");
    cli_return_freed_memory();
    int features = 1;
    for (int k = 0; k < NUM_PRESETS; k++)
        if (!strcmp(presets[k].name, method)) features = presets[k].features;
    if (!features) { /* guided by the colour alone */
        free(in.albedo);
        free(in.normal);
        free(in.depth);
        in.albedo = in.normal = in.depth = NULL;
    }
    /* the features are copied into `in` too, and go back into the file from
     * there, the same floats, before it is written: the file need not hold
     * them twice while the method works */
    feature_passes fp[4];
    const int nfp = layer_features(lp, &in, fp);
    for (int k = 0; k < nfp; k++) ewio_release_pass(j->f, layer, fp[k].pass, fp[k].comps);
    cli_return_freed_memory();
    ew_method_spec spec;
    char chosen[200] = "";
    make_spec(j, method, &spec);
    spec.chosen = chosen;
    spec.chosen_len = sizeof chosen;
    cli_progress prog;
    char what[300];
    snprintf(what, sizeof what, "denoise '%s'", layer[0] ? layer : "(image)");
    cli_progress_init(&prog, what, 1, j->o->quiet);
    spec.progress = cli_progress_cb;
    spec.progress_user = &prog;
    double ms = 0.0, warm_ms = -1.0;
    spec.warm_runs = cli_timing.warm_runs;
    spec.warm_ms = &warm_ms;
    /* features the file stores as halves, held as those halves when the
     * method's run reads halves where they are (the same values, half the
     * memory) */
    spec.holds = &in;
    spec.halves_allowed = ew_layer_halves_allowed(j->f, lp);
    cli_timing.read += cli_seconds() - t_read;
    /* the result goes over the colour (every denoiser takes its output
     * over its colour, and the do-no-harm stage keeps what it reads of the
     * colour after the method: what its rejection took), so the layer holds
     * one frame of RGB, not two; into j->out where the colour is read again
     * (--timings=N) or the result after the layer (--reference) */
    float *res = j->out ? j->out : in.color;
    int bad = ew_method_run(j->dev, &spec, &in, res, &ms, j->err, sizeof j->err);
    cli_timing.compute += ms * 1e-3;
    if (warm_ms >= 0.0) cli_timing.warm = warm_ms * 1e-3;
    cli_progress_end(&prog);
    const int guided = in.albedo != NULL;
    const int has_nd = in.normal && in.depth, has_n = in.normal != NULL, has_d = in.depth != NULL;
    char back_err[256] = "";
    int back = 0;
    /* the features go back unchanged: from the input file at write time
     * when it still holds them there, else the copies */
    for (int k = 0; k < nfp && back == 0; k++)
        back = ewio_pass_in_source(j->f, layer, fp[k].pass, fp[k].comps)
                   ? ewio_set_pass_from_source(j->f, layer, fp[k].pass, fp[k].comps, fp[k].pass, back_err,
                                               sizeof back_err)
                   : ewio_set_pass(j->f, layer, fp[k].pass, fp[k].comps, fp[k].data, back_err, sizeof back_err);
    float *color = in.color; /* may hold the result: freed after it is put into the file */
    in.color = NULL;
    ew_layer_data_free(&in);
    if (back != 0 && !bad) {
        ew_host_free(color);
        ew_host_free(orig);
        return cli_fail("%s", back_err);
    }
    if (bad) {
        ew_host_free(color);
        ew_host_free(orig);
        return cli_fail("denoising layer '%s' failed: %s", layer, j->err);
    }
    if (j->o->data_path) /* what ran is the file's */
        snprintf(chosen, sizeof chosen, "%s %s", lm, j->o->data_path);
    /* Keep the noisy original beside the result, as Blender does. The
     * layer's own buffers are lent to the file and written from there; a
     * result in j->out is copied (the next layer's goes there too). */
    int put = 0;
    if (keep_noisy && orig) {
        put = put_result(j, layer, "Noisy Image", lp->color_comps, orig);
        if (put == 0) orig = NULL;
    } else if (keep_noisy) {
        put = ewio_set_pass_from_source(j->f, layer, "Noisy Image", lp->color_comps, lp->color, j->err, sizeof j->err);
    }
    if (put == 0 && res == color) {
        put = put_result(j, layer, dst, "RGB", res);
        if (put == 0) color = NULL;
    } else if (put == 0) {
        put = ewio_set_pass(j->f, layer, dst, "RGB", res, j->err, sizeof j->err);
    }
    ew_host_free(color);
    ew_host_free(orig);
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

/* "11.8 GiB", "37.5 MiB": sizes for messages (a few per call, rotating) */
static const char *size_text(uint64_t bytes) {
    static char buf[6][32];
    static int next;
    char *b = buf[next++ % 6];
    if (bytes >= (1ull << 30)) snprintf(b, sizeof buf[0], "%.1f GiB", (double)bytes / (double)(1ull << 30));
    else snprintf(b, sizeof buf[0], "%.1f MiB", (double)bytes / (double)(1ull << 20));
    return b;
}

/* Before reading any pixels: the file's channels (as ewio holds them, float),
 * this command's buffers a pixel and the method's own memory (the library's
 * estimate for the frame's size with the parameters given) against the
 * memory limit. An 8K frame that cannot be denoised is refused in a moment,
 * not after minutes of reading. */
static int check_memory(const options *o, ew_device *dev) {
    char err[1024];
    ewio_header hd;
    if (ewio_read_header(o->in, &hd, err, sizeof err) != 0) return cli_fail("%s", err);
    const uint64_t limit = ewio_max_memory();
    if (!limit) return 0;
    const uint64_t n = (uint64_t)hd.width * (uint64_t)hd.height;
    const uint64_t file = n * (uint64_t)hd.channels * sizeof(float);
    /* the result and the first layer's noisy colour (3 each), the layer's
     * original colour kept as 'Noisy Image' (4), its colour, albedo, normal
     * and depth for the method (10), the added 'Noisy Image' pass (4) */
    const uint64_t buffers = n * 24 * sizeof(float);
    const char *lm = library_method(o->method);
    uint64_t method = 0;
    ew_op *op = NULL;
    if (ew_op_create(dev, lm, &op) == EW_OK) {
        for (int i = 0; i < o->num_set; i++) {
            if (!o->set_name[i]) continue;
            ew_param_info p;
            const int32_t k = param_index(lm, o->set_name[i]);
            if (k < 0 || ew_method_param("denoiser", lm, k, &p) != EW_OK) continue;
            if (p.type == EW_PARAM_FLOAT) ew_op_set_float(op, o->set_name[i], o->set_value[i]);
            else ew_op_set_int(op, o->set_name[i], (int32_t)o->set_value[i]);
        }
        if (o->data_name) ew_op_set_data(op, o->data_name, o->data_bytes, o->data_size);
        /* the sample count the run will give it (ew_layer_data_read), unless set */
        int samples_set = 0;
        for (int i = 0; i < o->num_set; i++) samples_set |= o->set_name[i] && !strcmp(o->set_name[i], "samples");
        if (!samples_set && hd.samples > 0 && param_index(lm, "samples") >= 0)
            ew_op_set_int(op, "samples", hd.samples);
        if (ew_op_memory(op, hd.width, hd.height, &method) != EW_OK) method = 0; /* no estimate: not counted */
        ew_op_destroy(op);
    }
    const uint64_t total = file + buffers + method;
    if (total <= limit) return 0;
    return cli_fail("denoising '%s' (%dx%d, %d channels) with --method %s needs about %s: the file %s, this "
                    "command's buffers %s, %s's working memory %s; above the memory limit of %s (--max-memory "
                    "raises it; the default is 3/4 of the physical memory). Nothing was read",
                    o->in, hd.width, hd.height, hd.channels, o->method, size_text(total), size_text(file),
                    size_text(buffers), lm, size_text(method), size_text(limit));
}

int cmd_denoise(int argc, char **argv) {
    options o;
    if (!parse(argc, argv, &o)) return EW_EXIT_USAGE;
    if (o.data_path && read_data(&o) != 0) return EW_EXIT_FAIL;
    if (same_file(o.in, o.out))
        return cli_fail("refusing to write the output over the input '%s': choose another -o", o.in);
    /* the reference is scored against after the write: it must survive it */
    if (o.reference && same_file(o.reference, o.out))
        return cli_fail("refusing to write the output over the reference '%s': choose another -o", o.reference);

    if (cli_check_image_output(o.out) != 0) return EW_EXIT_FAIL;
    if (cli_view_prepare(&o.view, o.out) != 0) return EW_EXIT_USAGE;
    job j;
    memset(&j, 0, sizeof j);
    j.o = &o;
    int rc = EW_EXIT_FAIL;
    if (!(j.dev = cli_device(o.threads, 1)) || check_memory(&o, j.dev) != 0) {
        cli_view_free(&o.view);
        ew_device_destroy(j.dev);
        return EW_EXIT_FAIL;
    }
    const double t_read = cli_seconds();
    /* the passes no layer's method reads stay in the file (ewio_load_passes below) */
    if (ewio_open(o.in, &j.f, j.err, sizeof j.err) != 0) {
        cli_view_free(&o.view);
        ew_device_destroy(j.dev);
        return cli_fail("%s", j.err);
    }
    cli_timing.read += cli_seconds() - t_read;
    const size_t n = (size_t)ewio_width(j.f) * (size_t)ewio_height(j.f);
    float *noisy_first = NULL;
    /* a result apart from the colour (denoise_layer) */
    const int own_out = o.reference || cli_timing.warm_runs > 0;
    if (own_out) j.out = (float *)malloc(n * 3 * sizeof(float));
    if (o.reference) noisy_first = (float *)malloc(n * 3 * sizeof(float)); /* scored after the first layer */
    if ((own_out && !j.out) || (o.reference && !noisy_first)) {
        cli_fail("out of memory for a %dx%d image", ewio_width(j.f), ewio_height(j.f));
        goto done;
    }

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
        /* the layer's colour and features are decoded in one pass over the
         * file (ew_layer_data_read); the motion vectors only for a method
         * that reads them (else they stay in the file, and are copied from
         * it when the result is written) */
        lp.skip_vector = !method_takes(o.method, "vector");
        if (done_layers == 0) {
            first = lp;
            if (noisy_first && ewio_get_pass(j.f, layer, lp.color, "RGB", noisy_first, j.err, sizeof j.err) != 0) {
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
    /* the results are in the file or lent to it: the write's memory is its own */
    free(j.out);
    free(noisy_first);
    j.out = noisy_first = NULL;
    cli_return_freed_memory();
    const double t_write = cli_seconds();
    if (cli_write(j.f, o.out, o.type, first.layer, wpass, &o.view, o.quiet, j.err, sizeof j.err) != 0) {
        cli_fail("%s", j.err);
        goto done;
    }
    cli_timing.write += cli_seconds() - t_write;
    if (!o.quiet) fprintf(stderr, "edgewise: wrote %s\n", o.out);
    rc = 0;
done:
    cli_view_free(&o.view);
    ew_device_destroy(j.dev);
    ewio_free(j.f);
    free_lent(&j);
    free(j.out);
    free(noisy_first);
    free(o.data_bytes);
    return rc;
}
