/* Fuzz target for image files through ewio (ewio.h: OpenEXR, and OpenImageIO
 * for other formats): those libraries are not ours, but our use of what they
 * return is — data windows, channel counts and names, parts, attributes,
 * layer/pass splitting. Any bytes
 * either read into a file whose every channel can be fetched, or are refused
 * with a message; never a crash, and never more memory than the limit set
 * below (the header checks run before any pixel memory). The check of a
 * written file's chunks (exr_header_scan.h) runs over the same bytes.
 * Built with clang -fsanitize=fuzzer for fuzzing (EW_FUZZ); in the ordinary
 * build replay_main.c runs it over the corpus as a test. */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ewio.h"
#include "exr_header_scan.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char path[64];

/* the one temporary every input is written to goes when the process ends */
static void remove_temporary(void) { unlink(path); }

static int prepare(void) {
    if (path[0]) return 1;
    /* small limits: a fuzzed header may declare anything */
    setenv("EDGEWISE_MAX_MEMORY", "4M", 1);
    setenv("EDGEWISE_MAX_PIXELS", "65536", 1);
    snprintf(path, sizeof path, "/tmp/ew_fuzz_exr_XXXXXX.exr");
    int fd = mkstemps(path, 4);
    if (fd < 0) return 0;
    close(fd);
    atexit(remove_temporary);
    return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (!prepare()) return 0;
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    if (size) fwrite(data, 1, size, f);
    fclose(f);
    /* the check a written file passes before it replaces anything reads
     * the same untrusted structure: an answer, never a crash */
    f = fopen(path, "rb");
    if (f) {
        ewio_exr_layout lay;
        char why[256] = "";
        const int r = ewio_exr_chunks_check(f, (long long)size, &lay, why, sizeof why);
        fclose(f);
        if (r < -1 || r > 1 || (r == 1 && !why[0])) __builtin_trap();
    }
    ewio_file *img = NULL;
    char err[512];
    if (ewio_read(path, &img, err, sizeof err) != 0) {
        if (img || err[0] == '\0') __builtin_trap(); /* no partial file; a refusal says why */
        return 0;
    }
    const int w = ewio_width(img), h = ewio_height(img), nch = ewio_num_channels(img);
    if (w <= 0 || h <= 0 || nch < 0 || (long long)w * h > 65536) __builtin_trap();
    float *buf = (float *)malloc((size_t)w * (size_t)h * sizeof(float));
    for (int c = 0; buf && c < nch; c++) {
        /* every channel, by the layer/pass/component split of its name */
        const char *name = ewio_channel_name(img, c);
        if (!name) __builtin_trap();
        for (int l = 0; l < ewio_num_layers(img); l++) (void)ewio_layer_name(img, l);
        const char *dot = strrchr(name, '.');
        const char *comp = dot ? dot + 1 : name;
        if (strlen(comp) != 1) continue; /* multi-letter components are not fetched by letter */
        char rest[512] = "", layer[512] = "", pass[512] = "";
        if (dot) snprintf(rest, sizeof rest, "%.*s", (int)(dot - name), name);
        const char *pdot = strrchr(rest, '.');
        if (pdot) {
            snprintf(layer, sizeof layer, "%.*s", (int)(pdot - rest), rest);
            snprintf(pass, sizeof pass, "%s", pdot + 1);
        } else {
            snprintf(pass, sizeof pass, "%s", rest);
        }
        if (ewio_get_pass(img, layer, pass, comp, buf, err, sizeof err) != 0 && !ewio_has_pass(img, layer, pass, comp))
            continue; /* a name that does not split back (e.g. a repeated name) */
    }
    free(buf);
    (void)ewio_get_attribute(img, "compression");
    ewio_free(img);
    return 0;
}
