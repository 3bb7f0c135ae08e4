/* A reading of an OpenEXR file's headers that trusts no size in them, run
 * before OpenImageIO opens the file: OpenEXR allocates what a header
 * declares (a string attribute's length, the chunk offset table, line and
 * tile buffers) before it finds the file too short, so a few hundred bytes
 * can ask it for gigabytes. The scan reads attribute by attribute and
 * refuses what the file's own size cannot hold; the caller then checks the
 * declared image against its pixel and memory limits. */
#ifndef EWIO_EXR_HEADER_SCAN_H
#define EWIO_EXR_HEADER_SCAN_H

#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ewio_exr_layout {
    int is_exr;                   /* 0: not an OpenEXR file (nothing else is set) */
    int parts;                    /* headers read */
    long long width, height;      /* the largest data window over the parts */
    long long tile_width, tile_height; /* the largest tile size (0: scanline parts only) */
    long long channels;           /* over every part */
} ewio_exr_layout;

/* Scans `f` (positioned anywhere; it is read from the start) of `file_size`
 * bytes. Returns 0 and fills *out when the headers are plausible or the file
 * is not an OpenEXR file; 1 with the reason in why[] when the headers declare
 * more than the file can hold (an attribute longer than the rest of the
 * file, an empty data window, a zero tile size, a chunk offset table past
 * the end). A header that is merely malformed is left to OpenEXR to report. */
int ewio_exr_header_scan(FILE *f, long long file_size, ewio_exr_layout *out, char *why, size_t whylen);

/* Whether a file just written holds all its pixel data: after the scan, the
 * chunk offset table of a one-part scanline file is read and every entry
 * must point inside the file, past the table, at a chunk that names the
 * lines it should hold and whose declared bytes the file holds. What a
 * write that failed unnoticed leaves — a file cut off, an offset table left
 * as the zeros OpenEXR writes first and fills in last, on close, where a
 * failure is not reported — is found without decoding any pixel. Returns 0
 * with the layout in *out when it holds, 1 with the reason in why[] when
 * not, -1 for a file of a kind it does not cover (several parts, tiles,
 * deep data, an unknown compression): then decode it to know. */
int ewio_exr_chunks_check(FILE *f, long long file_size, ewio_exr_layout *out, char *why, size_t whylen);

#ifdef __cplusplus
}
#endif

#endif
