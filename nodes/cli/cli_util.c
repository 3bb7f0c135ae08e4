#include <errno.h>
#include <stdint.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "cycles_passes.h"

int cli_fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("edgewise: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    return EW_EXIT_FAIL;
}

int cli_parse_int(const char *opt, const char *s, int lo, int hi, int *out) {
    char *end;
    errno = 0;
    long v = s ? strtol(s, &end, 10) : 0;
    if (!s || *s == '\0' || *end != '\0' || errno || v < lo || v > hi) {
        fprintf(stderr, "edgewise: %s expects an integer in [%d, %d], got '%s'\n", opt, lo, hi, s ? s : "");
        return 0;
    }
    *out = (int)v;
    return 1;
}

int cli_parse_float(const char *opt, const char *s, float lo, float hi, float *out) {
    char *end;
    errno = 0;
    float v = s ? strtof(s, &end) : 0.0f;
    if (!s || *s == '\0' || *end != '\0' || errno || !(v >= lo && v <= hi)) {
        fprintf(stderr, "edgewise: %s expects a number in [%g, %g], got '%s'\n", opt, (double)lo, (double)hi,
                s ? s : "");
        return 0;
    }
    *out = v;
    return 1;
}

float *cli_read_color(const ewio_file *f, const char *layer, char *err, size_t errlen) {
    ew_layer_passes lp;
    int found = 0;
    if (layer) {
        found = ew_find_image_passes(f, layer, &lp, err, errlen) == 0;
    } else {
        for (int i = 0; i < ewio_num_layers(f) && !found; i++)
            found = ew_find_image_passes(f, ewio_layer_name(f, i), &lp, err, errlen) == 0;
    }
    if (!found) return NULL;
    size_t n = (size_t)ewio_width(f) * (size_t)ewio_height(f);
    float *buf = (float *)malloc(n * 3 * sizeof(float));
    if (!buf) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    if (ewio_get_pass(f, lp.layer, lp.color, "RGB", buf, err, errlen) != 0) {
        free(buf);
        return NULL;
    }
    return buf;
}

ew_device *cli_device(int threads, int once) {
    ewio_set_threads(threads); /* the files' compression on the same threads */
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    desc.release_scratch = once && cli_timing.warm_runs == 0;
    ew_device *dev = NULL;
    ew_result r = ew_device_create(&desc, &dev);
    if (r != EW_OK) cli_fail("cannot create the device: %s", ew_result_string(r));
    return dev;
}

int cli_check_writable(const char *path) {
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash) snprintf(dir, sizeof dir, ".");
    else if (slash == dir) dir[1] = '\0';
    else *slash = '\0';
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return cli_fail("cannot write '%s': directory '%s' does not exist", path, dir);
    if (access(dir, W_OK) != 0) return cli_fail("cannot write '%s': directory '%s' is not writable", path, dir);
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) return cli_fail("cannot write '%s': it is a directory", path);
    return 0;
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
    float *buf = (float *)ew_host_alloc(n * sizeof(float));
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

int cli_keep_uniform_alpha(ewio_file *f, const char *layer, const char *pass, float **rgba, size_t n) {
    float *p = *rgba;
    uint32_t a0, b;
    memcpy(&a0, p + 3, sizeof a0);
    if ((a0 & 0x7f800000u) == 0x7f800000u || !ewio_pass_in_source(f, layer, pass, "A")) return 0;
    for (size_t i = 1; i < n; i++) {
        memcpy(&b, p + 4 * i + 3, sizeof b);
        if (b != a0) return 0;
    }
    if (ewio_set_pass_from_source(f, layer, pass, "A", pass, NULL, 0) != 0) return 0;
    for (size_t i = 0; i < n; i++) /* RGBA to RGB in place: pixel i's floats move down or stay */
        for (int c = 0; c < 3; c++) p[3 * i + (size_t)c] = p[4 * i + (size_t)c];
    float *q = (float *)realloc(p, n * 3 * sizeof(float));
    if (q) *rgba = q;
    return 1;
}

long cli_count_nonfinite(const float *v, size_t n) {
    long k = 0;
    for (size_t i = 0; i < n; i++) k += !(v[i] - v[i] == 0.0f);
    return k;
}

int cli_parse_view(int argc, char **argv, int *i, cli_view *v) {
    const char *a = argv[*i];
    if (!strcmp(a, "--raw")) {
        v->raw = 1;
        return 1;
    }
    if (strcmp(a, "--display") != 0 && strcmp(a, "--view") != 0) return 0;
    if (*i + 1 >= argc) {
        fprintf(stderr, "edgewise: %s needs a value\n", a);
        return -1;
    }
    *(a[2] == 'd' ? &v->display : &v->view) = argv[++*i];
    return 1;
}

/* Extensions ewio writes as integers for a scene-linear pass. */
static int integer_extension(const char *path) {
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash)) return 0;
    return !strcasecmp(dot, ".png") || !strcasecmp(dot, ".jpg") || !strcasecmp(dot, ".jpeg") ||
           !strcasecmp(dot, ".tif") || !strcasecmp(dot, ".tiff");
}

int cli_view_prepare(cli_view *v, const char *out_path) {
    v->proc = NULL;
    if (v->raw && (v->display || v->view)) {
        fprintf(stderr, "edgewise: --raw writes values without a display transform; drop --display/--view\n");
        return EW_EXIT_USAGE;
    }
    if (v->raw || !integer_extension(out_path)) return 0;
    char err[1024];
    if (ewcolor_display(NULL, v->display, v->view, NULL, 0.0f, 1.0f, &v->proc, err, sizeof err) != 0) {
        fprintf(stderr, "edgewise: %s\n", err);
        return EW_EXIT_USAGE;
    }
    return 0;
}

void cli_view_free(cli_view *v) {
    ewcolor_free(v->proc);
    v->proc = NULL;
}

int cli_write(ewio_file *f, const char *path, ewio_pixel_type type, const char *layer, const char *pass,
              const cli_view *v, int quiet, char *err, size_t errlen) {
    const int display = v && v->proc && ewio_write_is_integer(f, path, type, layer, pass) == 1 &&
                        !ewio_pass_read_as_integer(f, layer, pass);
    const char *comps = !display                               ? NULL
                        : ewio_has_pass(f, layer, pass, "RGBA") ? "RGBA"
                        : ewio_has_pass(f, layer, pass, "RGB")  ? "RGB"
                                                                : NULL;
    if (comps) { /* a colour pass in scene linear light: what a display shows */
        const int w = ewio_width(f), h = ewio_height(f), c = (int)strlen(comps);
        float *px = (float *)malloc((size_t)w * (size_t)h * (size_t)c * sizeof(float));
        if (!px) {
            snprintf(err, errlen, "out of memory");
            return 1;
        }
        int bad = ewio_get_pass(f, layer, pass, comps, px, err, errlen);
        if (!bad) {
            ewcolor_apply(v->proc, px, w, h, c);
            bad = ewio_set_pass(f, layer, pass, comps, px, err, errlen);
        }
        free(px);
        if (bad) return 1;
        if (!quiet) {
            char cfg[512], d[128], vw[128];
            ewcolor_config_name(cfg, sizeof cfg);
            ewcolor_default_view(v->display, d, sizeof d, vw, sizeof vw);
            fprintf(stderr, "edgewise: %s: display '%s', view '%s' (OpenColorIO config %s; --raw for linear values)\n",
                    path, d, v->view ? v->view : vw, cfg);
        }
    }
    return ewio_write(f, path, type, layer, pass, err, errlen);
}

/* ---- progress ---------------------------------------------------------- */

static double cli_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void cli_progress_init(cli_progress *p, const char *what, int frames, int quiet) {
    memset(p, 0, sizeof *p);
    p->what = what;
    p->frames = frames;
    p->enabled = !quiet && isatty(STDERR_FILENO);
    p->t0 = cli_now();
    p->last = -1.0;
}

static void fmt_time(double s, char *buf, size_t len) {
    long t = (long)(s + 0.5);
    if (t >= 3600) snprintf(buf, len, "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
    else snprintf(buf, len, "%ld:%02ld", t / 60, t % 60);
}

int cli_progress_cb(void *user, double fraction) {
    cli_progress *p = (cli_progress *)user;
    if (!p->enabled) return 1;
    const double now = cli_now();
    if (fraction < 0.0) fraction = 0.0;
    if (fraction > 1.0) fraction = 1.0;
    /* at most ten lines a second; a new frame and the end always */
    const int frame = p->frames > 1 ? (int)(fraction * p->frames + 1e-9) : 0;
    if (p->last >= 0.0 && now - p->last < 0.1 && fraction < 1.0 && frame == p->last_frame) return 1;
    p->last = now;
    p->last_frame = frame;
    const double elapsed = now - p->t0;
    char bar[31], left[32] = "", frames[48] = "";
    const int fill = (int)(fraction * 30.0);
    for (int i = 0; i < 30; i++) bar[i] = i < fill ? '#' : '.';
    bar[30] = '\0';
    if (fraction > 0.02 && elapsed > 0.5 && fraction < 1.0) {
        char t[24];
        fmt_time(elapsed * (1.0 - fraction) / fraction, t, sizeof t);
        snprintf(left, sizeof left, ", %s left", t);
    } else {
        char t[24];
        fmt_time(elapsed, t, sizeof t);
        snprintf(left, sizeof left, ", %s", t);
    }
    if (p->frames > 1) {
        snprintf(frames, sizeof frames, " frame %d/%d", frame < p->frames ? frame + 1 : p->frames, p->frames);
    }
    fprintf(stderr, "\r%s [%s] %3d%%%s%s\033[K", p->what, bar, (int)(fraction * 100.0), frames, left);
    fflush(stderr);
    p->drawn = 1;
    return 1;
}

void cli_progress_end(cli_progress *p) {
    if (p->enabled && p->drawn) {
        fputs("\r\033[K", stderr);
        fflush(stderr);
    }
    p->drawn = 0;
}
