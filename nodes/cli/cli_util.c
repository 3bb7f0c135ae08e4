#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
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
        found = ew_find_layer_passes(f, layer, &lp, err, errlen) == 0;
    } else {
        for (int i = 0; i < ewio_num_layers(f) && !found; i++)
            found = ew_find_layer_passes(f, ewio_layer_name(f, i), &lp, err, errlen) == 0;
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

ew_device *cli_device(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
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

long cli_count_nonfinite(const float *v, size_t n) {
    long k = 0;
    for (size_t i = 0; i < n; i++) k += !(v[i] - v[i] == 0.0f);
    return k;
}
