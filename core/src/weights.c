#include "src/weights.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

static const char magic[8] = {'E', 'W', 'W', 'E', 'I', 'G', 'H', 'T'};
/* the pyramid tables' magic before they moved into this container */
static const char pyramid_magic[8] = {'E', 'W', 'P', 'Y', 'R', 'W', 'T', 'S'};

uint32_t ew_crc32(const void *data, size_t size) { return (uint32_t)crc32_z(0uL, (const Bytef *)data, size); }

typedef struct { const unsigned char *p; size_t size, at; } reader;

static int rd_u32(reader *r, uint32_t *v) {
    if (r->size - r->at < 4) return 0;
    const unsigned char *b = r->p + r->at;
    *v = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    r->at += 4;
    return 1;
}

static int rd_str(reader *r, char *dst, size_t cap) {
    uint32_t n;
    if (!rd_u32(r, &n) || n >= cap || r->size - r->at < n) return 0;
    memcpy(dst, r->p + r->at, n);
    dst[n] = '\0';
    r->at += n;
    return 1;
}

void ew_weights_free(ew_weights *w) {
    if (!w) return;
    for (uint32_t i = 0; w->tensors && i < w->num_tensors; i++) free(w->tensors[i].data);
    free(w->tensors);
    memset(w, 0, sizeof *w);
}

#define EW_WEIGHTS_MAX_ABS 1e6f

#define FAIL(...) do { snprintf(err, errlen, __VA_ARGS__); ew_weights_free(out); return 1; } while (0)

int ew_weights_parse(const void *bytes, size_t size, ew_weights *out, char *err, size_t errlen) {
    memset(out, 0, sizeof *out);
    if (!bytes || size < sizeof magic + 8) FAIL("weights file is too small (%zu bytes)", size);
    if (memcmp(bytes, magic, sizeof magic) != 0 && memcmp(bytes, pyramid_magic, sizeof magic) != 0)
        FAIL("not an Edgewise weights file (bad magic)");
    reader r = {(const unsigned char *)bytes, size - 4, sizeof magic};
    uint32_t stored_crc = 0, version = 0;
    reader tail = {(const unsigned char *)bytes, size, size - 4};
    rd_u32(&tail, &stored_crc);
    if (ew_crc32(bytes, size - 4) != stored_crc) FAIL("weights file is damaged (checksum mismatch)");
    if (!rd_u32(&r, &version) || version != EW_WEIGHTS_VERSION)
        FAIL("weights file version %u is not supported (this library reads version %u)", version, EW_WEIGHTS_VERSION);
    if (!rd_str(&r, out->arch, sizeof out->arch)) FAIL("weights file: bad architecture string");
    uint32_t n;
    if (!rd_u32(&r, &n) || n == 0 || n > 4096) FAIL("weights file: bad tensor count");
    out->tensors = (ew_tensor *)calloc(n, sizeof(ew_tensor));
    if (!out->tensors) FAIL("out of memory reading weights");
    out->num_tensors = n;
    for (uint32_t i = 0; i < n; i++) {
        ew_tensor *t = &out->tensors[i];
        if (!rd_str(&r, t->name, sizeof t->name)) FAIL("weights file: bad name of tensor %u", i);
        if (!rd_u32(&r, &t->rank) || t->rank < 1 || t->rank > EW_WEIGHTS_MAX_RANK)
            FAIL("weights file: tensor '%s' has a bad rank", t->name);
        size_t count = 1;
        for (uint32_t k = 0; k < t->rank; k++) {
            if (!rd_u32(&r, &t->dims[k]) || t->dims[k] == 0 || t->dims[k] > (1u << 20))
                FAIL("weights file: tensor '%s' has a bad shape", t->name);
            count *= t->dims[k];
        }
        if (count > ((size_t)1 << 26) || (r.size - r.at) / 4 < count)
            FAIL("weights file: tensor '%s' is truncated", t->name);
        t->count = count;
        t->data = (float *)malloc(count * sizeof(float));
        if (!t->data) FAIL("out of memory reading weights");
        for (size_t k = 0; k < count; k++) {
            uint32_t u = 0;
            rd_u32(&r, &u);
            memcpy(&t->data[k], &u, 4);
            if (!isfinite(t->data[k])) FAIL("weights file: tensor '%s' holds a non-finite value", t->name);
            /* Trained weights stay within tens (the largest shipped is 32);
             * values near FLT_MAX only overflow the network into an all-NaN
             * (then black) output, so they are refused like non-finite ones. */
            if (fabsf(t->data[k]) > EW_WEIGHTS_MAX_ABS)
                FAIL("weights file: tensor '%s' holds %g, beyond any trained weight (|w| <= %g)", t->name,
                     (double)t->data[k], (double)EW_WEIGHTS_MAX_ABS);
        }
    }
    if (r.at != r.size) FAIL("weights file: %zu unexpected trailing bytes", r.size - r.at);
    return 0;
}
#undef FAIL

const ew_tensor *ew_weights_tensor(const ew_weights *w, const char *name) {
    for (uint32_t i = 0; i < w->num_tensors; i++)
        if (strcmp(w->tensors[i].name, name) == 0) return &w->tensors[i];
    return NULL;
}

const ew_tensor *ew_weights_find(const ew_weights *w, const char *name, uint32_t rank, const uint32_t *dims,
                                 char *err, size_t errlen) {
    const ew_tensor *t = ew_weights_tensor(w, name);
    if (!t) {
        snprintf(err, errlen, "weights '%s': no tensor '%s'", w->arch, name);
        return NULL;
    }
    int same = t->rank == rank;
    for (uint32_t k = 0; same && k < rank; k++) same = t->dims[k] == dims[k];
    if (!same) {
        snprintf(err, errlen, "weights '%s': tensor '%s' has the wrong shape for this architecture", w->arch, name);
        return NULL;
    }
    return t;
}

int ew_weights_get_conv(const ew_weights *w, int l, int cin, int cout, float *params, size_t w_off, size_t b_off,
                        char *err, size_t errlen) {
    char name[EW_WEIGHTS_MAX_NAME];
    const uint32_t wd[4] = {(uint32_t)cout, (uint32_t)cin, 5, 5}, bd[1] = {(uint32_t)cout};
    snprintf(name, sizeof name, "conv%d.weight", l);
    const ew_tensor *t = ew_weights_find(w, name, 4, wd, err, errlen);
    if (!t) return 1;
    memcpy(params + w_off, t->data, t->count * sizeof(float));
    snprintf(name, sizeof name, "conv%d.bias", l);
    t = ew_weights_find(w, name, 1, bd, err, errlen);
    if (!t) return 1;
    memcpy(params + b_off, t->data, t->count * sizeof(float));
    return 0;
}

void ew_weights_put_conv(ew_tensor t[2], int l, int cin, int cout, const float *params, size_t w_off, size_t b_off) {
    memset(t, 0, 2 * sizeof *t);
    snprintf(t[0].name, sizeof t[0].name, "conv%d.weight", l);
    t[0].rank = 4;
    t[0].dims[0] = (uint32_t)cout;
    t[0].dims[1] = (uint32_t)cin;
    t[0].dims[2] = t[0].dims[3] = 5;
    t[0].count = (size_t)cout * (size_t)cin * 25;
    t[0].data = (float *)(params + w_off); /* only read by ew_weights_serialize */
    snprintf(t[1].name, sizeof t[1].name, "conv%d.bias", l);
    t[1].rank = 1;
    t[1].dims[0] = (uint32_t)cout;
    t[1].count = (size_t)cout;
    t[1].data = (float *)(params + b_off);
}

/* p NULL: only counts the bytes */
typedef struct { unsigned char *p; size_t at; } writer;

static void wr_u32(writer *w, uint32_t v) {
    if (w->p) {
        w->p[w->at] = (unsigned char)v;
        w->p[w->at + 1] = (unsigned char)(v >> 8);
        w->p[w->at + 2] = (unsigned char)(v >> 16);
        w->p[w->at + 3] = (unsigned char)(v >> 24);
    }
    w->at += 4;
}

static void wr_bytes(writer *w, const void *src, size_t n) {
    if (w->p) memcpy(w->p + w->at, src, n);
    w->at += n;
}

static void emit(const ew_weights *wt, writer *w) {
    wr_bytes(w, magic, sizeof magic);
    wr_u32(w, EW_WEIGHTS_VERSION);
    wr_u32(w, (uint32_t)strlen(wt->arch));
    wr_bytes(w, wt->arch, strlen(wt->arch));
    wr_u32(w, wt->num_tensors);
    for (uint32_t i = 0; i < wt->num_tensors; i++) {
        const ew_tensor *t = &wt->tensors[i];
        wr_u32(w, (uint32_t)strlen(t->name));
        wr_bytes(w, t->name, strlen(t->name));
        wr_u32(w, t->rank);
        for (uint32_t k = 0; k < t->rank; k++) wr_u32(w, t->dims[k]);
        for (size_t k = 0; k < t->count; k++) {
            uint32_t u;
            memcpy(&u, &t->data[k], 4);
            wr_u32(w, u);
        }
    }
}

size_t ew_weights_write(const ew_weights *wt, void *buf, size_t cap) {
    writer sizing = {NULL, 0};
    emit(wt, &sizing);
    const size_t size = sizing.at + 4;
    if (!buf || cap < size) return size;
    writer w = {(unsigned char *)buf, 0};
    emit(wt, &w);
    wr_u32(&w, ew_crc32(buf, sizing.at));
    return size;
}

int ew_weights_serialize(const ew_weights *wt, void **out, size_t *size) {
    const size_t n = ew_weights_write(wt, NULL, 0);
    void *buf = malloc(n);
    if (!buf) return 1;
    ew_weights_write(wt, buf, n);
    *out = buf;
    *size = n;
    return 0;
}
