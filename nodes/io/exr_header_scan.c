/* OpenEXR header scan before OpenImageIO opens a file (see the header).
 * Layout (openexr.com, "OpenEXR File Layout"): magic, version flags, then
 * one header (several for a multi-part file, ended by an empty one) of
 * attributes `name\0 type\0 int32 size, value`, each header ended by a
 * null byte; then each part's chunk offset table, 8 bytes a chunk. */
#define _FILE_OFFSET_BITS 64
#define _POSIX_C_SOURCE 200809L
#include "exr_header_scan.h"

#include <stdarg.h>
#include <stdint.h>
#include <string.h>

enum {
    kTiledFlag = 0x200,
    kMultipartFlag = 0x1000,
    kNameMax = 256, /* 255 characters with the long-names flag, 31 without */
};

typedef struct part {
    int have_window, have_tiles, tiled, deep;
    long long xmin, ymin, xmax, ymax;
    long long tx, ty;
    int compression; /* -1: not given */
    long long chunk_count; /* -1: not given */
    long long channels;
} part;

static int get_bytes(FILE *f, unsigned char *b, size_t n) { return fread(b, 1, n, f) == n; }

static long long le64(const unsigned char *b) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | b[i];
    return v > (uint64_t)INT64_MAX ? -1 : (long long)v;
}

static long long le32(const unsigned char *b) {
    return (long long)(int32_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24);
}

static unsigned long long le32u(const unsigned char *b) {
    return (unsigned long long)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24);
}

/* A null-terminated name of at most kNameMax-1 characters; -1 when the file
 * ends or the name is longer (OpenEXR refuses both itself). */
static int get_name(FILE *f, char *s, long long *left) {
    for (int n = 0; n < kNameMax; n++) {
        int c = fgetc(f);
        if (c == EOF) return -1;
        --*left;
        s[n] = (char)c;
        if (c == 0) return n;
    }
    return -1;
}

/* Lines a scanline chunk holds for each compression (none, rle, zips, zip,
 * piz, pxr24, b44, b44a, dwaa, dwab); an unknown one counts as the most. */
static long long lines_per_chunk(int compression) {
    static const int lines[] = {1, 1, 1, 16, 32, 16, 32, 32, 32, 256};
    return compression >= 0 && compression < 10 ? lines[compression] : 256;
}

static long long ceil_div(long long a, long long b) { return (a + b - 1) / b; }

/* The fewest chunks the part can have: its offset table has one entry each
 * (tiled parts: the first level's tiles only). Saturates at `cap`. */
static long long min_chunks(const part *p, long long cap) {
    const long long w = p->xmax - p->xmin + 1, h = p->ymax - p->ymin + 1;
    long long n;
    if (p->tiled && p->have_tiles) {
        const long long cx = ceil_div(w, p->tx), cy = ceil_div(h, p->ty);
        n = cx > cap || cy > cap || (cx && cy > cap / cx) ? cap + 1 : cx * cy;
    } else {
        n = ceil_div(h, lines_per_chunk(p->compression));
    }
    if (p->chunk_count > n) n = p->chunk_count;
    return n > cap ? cap + 1 : n;
}

__attribute__((format(printf, 3, 4))) static int refuse(char *why, size_t whylen, const char *fmt, ...) {
    if (why && whylen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(why, whylen, fmt, ap);
        va_end(ap);
    }
    return 1;
}

/* A channel list entry the reader cannot take: OpenImageIO aborts the
 * process on a pixel type other than UINT, HALF and FLOAT (0, 1, 2). */
typedef struct {
    int found; /* 0 none, 1 pixel type, 2 sampling below 1 */
    long long value;
    char name[kNameMax];
} bad_channel;

/* Counts the entries of a channel list; the first bad entry goes to *bad and
 * the bytes the list takes to *used. OpenEXR reads entries up to the empty
 * name whatever the attribute's size says, so the list is read the same way
 * (bounded by the rest of the file, `avail`) and its length compared with
 * the declared size by the caller: where they differ, OpenEXR goes on
 * reading the rest of the header out of step with its attributes. */
static long long count_channels(FILE *f, long long avail, bad_channel *bad, long long *used) {
    long long n = 0, left = avail;
    char name[kNameMax];
    unsigned char e[16];
    *used = -1;
    for (;;) {
        const int len = get_name(f, name, &left);
        if (len < 0) return n; /* malformed or cut off: *used stays -1 */
        if (len == 0) break;   /* the list's end */
        if (left < 16 || !get_bytes(f, e, 16)) return n;
        left -= 16;
        const long long type = le32(e), xs = le32(e + 8), ys = le32(e + 12);
        if (!bad->found && (type < 0 || type > 2 || xs < 1 || ys < 1)) {
            bad->found = type < 0 || type > 2 ? 1 : 2;
            bad->value = bad->found == 1 ? type : (xs < 1 ? xs : ys);
            memcpy(bad->name, name, kNameMax);
        }
        n++;
    }
    *used = avail - left;
    return n;
}

/* The bytes OpenEXR reads for a value of a fixed-size type whatever size the
 * attribute declares (Imf TypedAttribute<T>::readValueFrom); 0 for a type of
 * variable size (string, vectors, chlist, preview, opaque). */
static long long fixed_size(const char *type) {
    static const struct {
        const char *name;
        int size;
    } types[] = {
        {"box2i", 16},  {"box2f", 16},    {"compression", 1}, {"chromaticities", 32}, {"deepImageState", 1},
        {"double", 8},  {"envmap", 1},    {"float", 4},       {"int", 4},             {"keycode", 28},
        {"lineOrder", 1}, {"m33f", 36},   {"m33d", 72},       {"m44f", 64},           {"m44d", 128},
        {"rational", 8}, {"tiledesc", 9}, {"timecode", 8},    {"v2i", 8},             {"v2f", 8},
        {"v2d", 16},    {"v3i", 12},      {"v3f", 12},        {"v3d", 24},
    };
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (!strcmp(type, types[i].name)) return types[i].size;
    return 0;
}

/* The scan; *first gets the first part's header and *table where the
 * offset tables begin (just after the headers). */
static int scan(FILE *f, long long file_size, ewio_exr_layout *out, char *why, size_t whylen, part *first,
                long long *table) {
    memset(out, 0, sizeof *out);
    memset(first, 0, sizeof *first);
    *table = -1;
    if (why && whylen) why[0] = '\0';
    unsigned char b[16];
    if (fseeko(f, 0, SEEK_SET) != 0 || !get_bytes(f, b, 8)) return 0;
    if (b[0] != 0x76 || b[1] != 0x2f || b[2] != 0x31 || b[3] != 0x01) return 0;
    out->is_exr = 1;
    const unsigned long long flags = le32u(b + 4);
    const int multipart = (flags & kMultipartFlag) != 0;
    long long left = file_size - 8, chunks = 0;
    char name[kNameMax], type[kNameMax];
    for (;;) {
        part p = {0, 0, (flags & kTiledFlag) != 0, 0, 0, 0, 0, 0, 0, 0, -1, -1, 0};
        int attrs = 0;
        for (;;) {
            const int nlen = get_name(f, name, &left);
            if (nlen < 0) return 0; /* malformed: OpenEXR says so */
            if (nlen == 0) break;   /* the header's end */
            if (get_name(f, type, &left) < 0 || left < 4 || !get_bytes(f, b, 4)) return 0;
            left -= 4;
            const long long size = le32(b);
            if (size < 0 || size > left)
                return refuse(why, whylen,
                              "the header's attribute '%s' declares %lld bytes, but the file has %lld "
                              "left (a damaged or truncated file)",
                              name, size, left);
            attrs++;
            const long long fixed = fixed_size(type);
            if (fixed && size != fixed)
                return refuse(why, whylen,
                              "the header's attribute '%s' of type %s declares %lld bytes, but that type "
                              "has %lld (a damaged file)",
                              name, type, size, fixed);
            long long used = 0;
            if (!strcmp(name, "dataWindow") && !strcmp(type, "box2i") && size == 16) {
                if (!get_bytes(f, b, 16)) return 0;
                p.have_window = 1;
                p.xmin = le32(b), p.ymin = le32(b + 4), p.xmax = le32(b + 8), p.ymax = le32(b + 12);
                used = 16;
            } else if (!strcmp(name, "tiles") && !strcmp(type, "tiledesc") && size == 9) {
                if (!get_bytes(f, b, 9)) return 0;
                p.have_tiles = 1;
                p.tx = (long long)le32u(b), p.ty = (long long)le32u(b + 4);
                used = 9;
            } else if (!strcmp(name, "compression") && !strcmp(type, "compression") && size == 1) {
                if (!get_bytes(f, b, 1)) return 0;
                p.compression = b[0];
                used = 1;
            } else if (!strcmp(name, "chunkCount") && !strcmp(type, "int") && size == 4) {
                if (!get_bytes(f, b, 4)) return 0;
                p.chunk_count = le32(b);
                if (p.chunk_count < 0)
                    return refuse(why, whylen, "the header declares %lld chunks", p.chunk_count);
                used = 4;
            } else if (!strcmp(name, "type") && !strcmp(type, "string")) {
                char t[16] = "";
                used = size < (long long)sizeof t - 1 ? size : (long long)sizeof t - 1;
                if (!get_bytes(f, (unsigned char *)t, (size_t)used)) return 0;
                p.tiled = !strcmp(t, "tiledimage") || !strcmp(t, "deeptile");
                p.deep = !strcmp(t, "deepscanline") || !strcmp(t, "deeptile");
            } else if (!strcmp(type, "preview")) {
                /* OpenEXR allocates width x height RGBA pixels before reading them */
                if (size < 8 || !get_bytes(f, b, 8))
                    return refuse(why, whylen, "the header's preview image '%s' is cut off (a damaged file)", name);
                const unsigned long long pw = le32u(b), ph = le32u(b + 4);
                if (pw * ph * 4 != (unsigned long long)size - 8)
                    return refuse(why, whylen,
                                  "the header's preview image declares %llu x %llu pixels in %lld bytes "
                                  "(a damaged file)",
                                  pw, ph, size);
                used = 8;
            } else if (!strcmp(type, "chlist")) {
                /* by its type, whatever its name: OpenEXR reads every chlist
                 * attribute up to its empty entry name */
                bad_channel bad;
                memset(&bad, 0, sizeof bad);
                long long list = 0;
                const long long n = count_channels(f, left, &bad, &list);
                if (list < 0) return 0; /* malformed: OpenEXR says so */
                if (list != size)
                    return refuse(why, whylen,
                                  "the header's channel list '%s' declares %lld bytes, but its entries take "
                                  "%lld (a damaged file)",
                                  name, size, list);
                if (bad.found == 1)
                    return refuse(why, whylen,
                                  "the header's channel '%s' has pixel type %lld (EXR knows 0 uint, 1 half, 2 float)",
                                  bad.name, bad.value);
                if (bad.found == 2)
                    return refuse(why, whylen, "the header's channel '%s' has a sampling of %lld (at least 1)",
                                  bad.name, bad.value);
                if (!strcmp(name, "channels")) p.channels = n;
                used = size;
            }
            if (size > used && fseeko(f, (off_t)(size - used), SEEK_CUR) != 0) return 0;
            left -= size;
        }
        if (attrs == 0) break; /* the empty header that ends a multi-part list */
        /* a required attribute: without it OpenEXR takes a default window
         * whose offset table this file need not have room for, and rebuilds
         * the table from whatever follows (one such header made it ask for
         * over 512 MB) */
        if (!p.have_window)
            return refuse(why, whylen, "the header of part %d has no data window (a damaged file)", out->parts);
        if (out->parts == 0) *first = p;
        out->parts++;
        out->channels += p.channels;
        if (p.have_window) {
            const long long w = p.xmax - p.xmin + 1, h = p.ymax - p.ymin + 1;
            if (w < 1 || h < 1)
                return refuse(why, whylen, "the header's data window is empty (%lld x %lld pixels)", w, h);
            if (w > out->width) out->width = w;
            if (h > out->height) out->height = h;
        }
        if (p.tiled && p.have_tiles) {
            if (p.tx < 1 || p.ty < 1)
                return refuse(why, whylen, "the header declares tiles of %lld x %lld pixels", p.tx, p.ty);
            if (p.tx > out->tile_width) out->tile_width = p.tx;
            if (p.ty > out->tile_height) out->tile_height = p.ty;
        }
        if (p.have_window) {
            const long long cap = 1LL << 60, n = min_chunks(&p, cap);
            chunks = n > cap - chunks ? cap : chunks + n;
        }
        if (!multipart) break;
    }
    /* one 8-byte offset a chunk, after the last header */
    *table = file_size - left;
    if (chunks > left / 8)
        return refuse(why, whylen,
                      "the header declares at least %lld chunks, but the %lld bytes after the headers cannot "
                      "hold their offset table (a damaged or truncated file)",
                      chunks, left);
    return 0;
}

int ewio_exr_header_scan(FILE *f, long long file_size, ewio_exr_layout *out, char *why, size_t whylen) {
    part first;
    long long table;
    return scan(f, file_size, out, why, whylen, &first, &table);
}

int ewio_exr_chunks_check(FILE *f, long long file_size, ewio_exr_layout *out, char *why, size_t whylen) {
    part p;
    long long table;
    if (scan(f, file_size, out, why, whylen, &p, &table) != 0) return 1;
    if (!out->is_exr) return refuse(why, whylen, "it is not an OpenEXR file");
    if (out->parts != 1 || p.tiled || p.deep || !p.have_window || p.compression < 0 || p.compression > 9 ||
        table < 0)
        return -1;
    const long long lines = lines_per_chunk(p.compression), n = ceil_div(p.ymax - p.ymin + 1, lines);
    const long long table_end = table + 8 * n; /* n fits: the scan checked the table against the file */
    unsigned char b[8];
    for (long long i = 0; i < n; i++) {
        if (fseeko(f, (off_t)(table + 8 * i), SEEK_SET) != 0 || !get_bytes(f, b, 8))
            return refuse(why, whylen, "its chunk offset table is cut off");
        const long long at = le64(b), y = p.ymin + i * lines;
        /* each chunk: int32 first line, int32 byte count, the bytes */
        if (at < table_end || at > file_size - 8)
            return refuse(why, whylen,
                          "the chunk of lines %lld.. is not in the file (offset %lld, the file has %lld bytes)", y,
                          at, file_size);
        if (fseeko(f, (off_t)at, SEEK_SET) != 0 || !get_bytes(f, b, 8))
            return refuse(why, whylen, "the chunk of lines %lld.. is cut off", y);
        const long long cy = le32(b), size = le32(b + 4);
        if (cy != y) return refuse(why, whylen, "the chunk of lines %lld.. says it holds line %lld", y, cy);
        if (size <= 0 || size > file_size - at - 8)
            return refuse(why, whylen,
                          "the chunk of lines %lld.. declares %lld bytes, but the file has %lld after its start", y,
                          size, file_size - at - 8);
    }
    return 0;
}
