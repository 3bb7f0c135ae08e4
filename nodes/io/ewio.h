/*
 * ewio.h — C interface to image files (ewio.cpp), the only place that reads
 * or writes them: EXR through OpenEXR, every other format through
 * OpenImageIO, loaded the first time such a file is met (codec.h).
 *
 * A file is loaded whole into memory: every channel as float32 (remembering
 * the type it was stored with), plus the header metadata, so it can be
 * written back with some passes replaced or added while all other layers,
 * channels and metadata are kept.
 *
 * Channel naming follows Blender's multilayer EXR:
 *   "<layer>.<pass>.<component>", e.g. "ViewLayer.Denoising Albedo.R".
 * Split as Blender itself does (imb_exr_split_channel_name): the component
 * is after the last '.', the pass is the token before it, the layer is
 * everything before that — so layer names may contain dots and spaces
 * ("ViewLayer.001.Combined.R" is layer "ViewLayer.001", Blender's default
 * name for a second view layer), pass names may contain spaces but no dots.
 * "Combined.R" is layer "" pass "Combined"; "R" is layer "" pass "".
 * A plain file (PNG/TIFF/flat EXR with R,G,B[,A]) thus has one layer named ""
 * with one pass named "" whose components are R,G,B[,A]. Integer images
 * (PNG, 8/16-bit TIFF) read as 0..1; with an alpha channel, colour is
 * associated (premultiplied), as in EXR, and un-premultiplied on PNG/TIFF
 * output (OpenImageIO's convention).
 *
 * Every function returning int returns 0 on success and non-zero on failure,
 * with a one-line message (no trailing newline, truncated to errlen) in err
 * (if err != NULL). Nothing is printed and no exception escapes — except
 * that libpng itself prints "libpng error: ..." to stderr on a corrupt PNG
 * (OpenImageIO 2.4 installs no libpng error callback); the call still fails
 * cleanly. Different ewio_file objects may be used from different threads.
 */
#ifndef EDGEWISE_EWIO_H
#define EDGEWISE_EWIO_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ewio_file ewio_file;

/* Read a whole image file (EXR, multilayer EXR, PNG, TIFF, anything
 * OpenImageIO reads). Fails cleanly on missing, unreadable, truncated or non-image files,
 * on zero/negative dimensions, on images above 65536 px per side or
 * ewio_max_pixels() pixels, and on files whose every channel as float would
 * take more than ewio_max_memory() bytes — all checked from the headers
 * before any pixel memory is allocated (and pixel memory becomes resident
 * only as the pixels are read). On failure *out is NULL: no partial image is
 * ever returned. Non-finite values are kept as read. Multi-part EXRs: every
 * part must have the size and origin of the first (a file with other parts
 * is refused, naming the part) and all are merged; a channel name already
 * taken gets the part's name as prefix. Deep and 3D images are refused. */
int ewio_read(const char *path, ewio_file **out, char *err, size_t errlen);
void ewio_free(ewio_file *f); /* NULL is a no-op */

/* As ewio_read, with the same checks, but the pixels of a scanline EXR
 * stay in the file: names, layers and metadata are read, and each
 * channel's pixels are decoded only when they are asked for
 * (ewio_get_pass decodes them into its dst; ewio_load_passes keeps them)
 * or written (ewio_write copies them from the source, band by band). So
 * passes a command does not use are never held as float planes. The values
 * are the ones ewio_read would hold. A later decode refuses a source that
 * is no longer the file that was read (another inode, size or modification
 * time) with a message; the write then fails and leaves its destination as
 * it was. Other files (tiled EXR, PNG, TIFF...) are read whole, as by
 * ewio_read. */
int ewio_open(const char *path, ewio_file **out, char *err, size_t errlen);

/* Decode the listed passes of a file from ewio_open (the channels still in
 * the file; comps NULL = every component of the pass) in one pass over
 * the file and keep them, so several ewio_get_pass calls do not each
 * decode it. Passes that do not exist are skipped (ewio_get_pass reports
 * them). A ref with `dst` is not kept: its pass is decoded into dst as
 * ewio_get_pass would copy it (comps required; a missing component fails
 * the call) and stays in the file — for the pass a caller works on in a
 * buffer of its own, which then is neither held twice nor copied. 0 on
 * success; on failure nothing is loaded (a dst may be partly written). */
typedef struct ewio_pass_ref {
    const char *layer, *pass, *comps;
    float *dst;
} ewio_pass_ref;
int ewio_load_passes(ewio_file *f, const ewio_pass_ref *refs, int n, char *err, size_t errlen);

/* What ewio_read would read, from the headers alone, with the same checks
 * (file type, size and channel limits, every part): size and the number of
 * channels over all parts. Lets a command refuse work that will not fit
 * before it reads the pixels. 0 on success. */
typedef struct ewio_header {
    int width, height, channels;
    int samples; /* Cycles' sample count (cycles.<layer>.samples) when every layer gives the same, else 0 */
} ewio_header;
int ewio_read_header(const char *path, ewio_header *out, char *err, size_t errlen);

/* The read limits, from the environment, so every reader in the process (the
 * CLI's commands and the graph's read nodes alike) applies the same ones:
 * EDGEWISE_MAX_PIXELS (at most, and by default, 2^28) and
 * EDGEWISE_MAX_MEMORY (bytes, or with a K/M/G/T suffix in powers of 1024;
 * default 3/4 of the physical memory). The CLI's --max-pixels and
 * --max-memory set them. */
unsigned long long ewio_max_memory(void);
long long ewio_max_pixels(void);
/* Threads that decode and encode files (OpenEXR's compression, OIIO's
 * own work), for the whole process: n as a device's num_threads (0 = as
 * many as the machine has cores), so a run limited to n threads does its
 * I/O on n too. */
void ewio_set_threads(int n);

/* "8G", "512M", "1.5T", "1000000" -> bytes; 0 on success. */
int ewio_parse_size(const char *text, unsigned long long *out);

/* Accessors: 0 / NULL for a NULL file or an index out of range. Returned
 * names stay valid until the next ewio_set_pass on the file or ewio_free. */
int ewio_width(const ewio_file *f);
int ewio_height(const ewio_file *f);
int ewio_num_channels(const ewio_file *f);
const char *ewio_channel_name(const ewio_file *f, int i);

/* Layers in order of first appearance. A plain RGB(A) file has one layer "". */
int ewio_num_layers(const ewio_file *f);
const char *ewio_layer_name(const ewio_file *f, int i);

/* Copy pass `pass` of `layer` into `dst` as interleaved float32,
 * width*height*strlen(comps) floats, components in the order of `comps`
 * (one letter each: "RGB", "XYZ", "Z", "RGBA"...). Returns non-zero with a
 * message naming the missing layer/pass/components and listing the layers
 * found if any component is absent (dst is then untouched). NULL layer or
 * pass means "". */
int ewio_get_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps,
                  float *dst, char *err, size_t errlen);
/* Free the pixels of the pass's components `comps` (as ewio_get_pass; names,
 * order and stored types stay), for a caller that has copied them out and
 * will put its result back with ewio_set_pass: the image is then not held
 * twice while it works. Until they are set again, ewio_get_pass and
 * ewio_write refuse them (ewio_has_pass still sees them). Non-zero, and
 * nothing freed, if a component is missing. */
int ewio_release_pass(ewio_file *f, const char *layer, const char *pass, const char *comps);

/* 1 if all components of the pass exist. */
int ewio_has_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps);

/* Replace the pass's channels (or add them, after the layer's other channels)
 * from interleaved float32 data of the file's size. Existing channels are
 * overwritten in place (no second copy of the pass is allocated, unless it
 * was released) and keep their stored type; new ones are inserted after
 * the pass's last channel, else after the layer's last channel, else at the
 * end, and are stored as half under EWIO_KEEP. Refused (file unchanged): a
 * named layer with an empty pass, a pass name with a dot, repeated
 * components — names that would not read back as the same layer/pass. */
int ewio_set_pass(ewio_file *f, const char *layer, const char *pass, const char *comps,
                  const float *src, char *err, size_t errlen);
/* As ewio_set_pass, but the file points at src instead of copying it (and
 * drops the pass's own pixels): src must stay valid and unchanged until the
 * file is written for the last time or freed, or the pass is set, lent or
 * released again. For a result that is only written: no second frame is
 * allocated and filled for it. */
int ewio_lend_pass(ewio_file *f, const char *layer, const char *pass, const char *comps,
                   const float *src, char *err, size_t errlen);

/* 1 if every component of the pass is in the file the data was read from
 * (a scanline EXR), which still holds the values it was read with whatever
 * ewio_set_pass or ewio_release_pass did to them since. */
int ewio_pass_in_source(const ewio_file *f, const char *layer, const char *pass, const char *comps);

/* 1 when every channel of the pass was read as half (stored so in the
 * file): its floats converted back with ewio_floats_to_half are the very
 * halves stored, and a caller may hold them so (EW_FORMAT_HALF views) at
 * no loss. */
int ewio_pass_stored_half(const ewio_file *f, const char *layer, const char *pass, const char *comps);
/* float -> half, rounding to nearest even (as OpenEXR's half(float)) */
void ewio_floats_to_half(const float *src, uint16_t *dst, size_t n);

/* Set pass (layer, pass, comps) to the values pass `from_pass` of the same
 * layer was read with (ewio_pass_in_source must hold for it), as
 * ewio_set_pass would with a copy of them taken at read time, but without
 * holding them: they are decoded from the source when read or written
 * (the source must then still be that file, as for ewio_open). New
 * channels go where ewio_set_pass puts them, stored as half under
 * EWIO_KEEP; existing ones keep their type. Refused as ewio_set_pass
 * refuses names. */
int ewio_set_pass_from_source(ewio_file *f, const char *layer, const char *pass, const char *comps,
                              const char *from_pass, char *err, size_t errlen);

/* Header metadata as text ("" if absent), e.g. "cycles.ViewLayer.samples",
 * "compression" (EXR input only). The pointer stays valid until that
 * attribute is set again or the file is freed. Names are case-sensitive.
 * ewio_set_attribute: NULL value removes the attribute; an existing int or
 * float attribute keeps its type if the text parses as one, anything else
 * is stored as a string. Setting "compression" chooses the EXR compression
 * ("zip", "piz", "dwaa", "none"...). */
const char *ewio_get_attribute(const ewio_file *f, const char *name);
int ewio_set_attribute(ewio_file *f, const char *name, const char *value);

typedef enum ewio_pixel_type {
    EWIO_KEEP = 0,  /* each channel keeps the type it was read with (new ones: half) */
    EWIO_HALF = 1,
    EWIO_FLOAT = 2
} ewio_pixel_type;

/* Write atomically: to a temporary file ".<name>.tmp-XXXXXX.<ext>" in the
 * destination directory, which is read back whole to check it, then renamed
 * over `path` (a symlink at `path` is replaced, not followed). On failure
 * nothing at `path` is touched and the temporary is removed. An existing
 * destination's permission bits are kept.
 * The format follows the extension (.exr, .png, .tif/.tiff, .jpg/.jpeg):
 * - EXR: one part with all channels in order and all metadata; compression
 *   of the input EXR (or the "compression" attribute), zip otherwise;
 *   `layer`/`pass` are ignored (may be NULL). `type` as below.
 * - PNG/TIFF/JPEG: only pass `pass` of `layer` (NULL = ""), as R,G,B(,A)
 *   (or X,Y,Z as R,G,B, or a single channel as grey); JPEG drops alpha.
 *   PNG/JPEG are 8-bit (16-bit PNG if the pass was read as 16-bit and type
 *   is EWIO_KEEP), TIFF is float (EWIO_KEEP: 8/16-bit if read so; EWIO_HALF:
 *   half); integer output is clamped to 0..1 with NaN written as 0. Values
 *   are written as they are: colour transforms are the caller's job. String
 *   metadata without a "prefix:" is copied.
 * Refuses to write over the file the data was read from (same device and
 * inode now, or the same resolved path as at read time). */
int ewio_write(const ewio_file *f, const char *path, ewio_pixel_type type,
               const char *layer, const char *pass, char *err, size_t errlen);

/* How ewio_write(f, path, type, layer, pass) stores samples: 1 as 8/16-bit
 * integers clamped to 0..1 (PNG, JPEG, a TIFF of a pass read as integers
 * under EWIO_KEEP), i.e. display values; 0 as floats (EXR, float TIFF);
 * -1 for an extension it does not write. */
int ewio_write_is_integer(const ewio_file *f, const char *path, ewio_pixel_type type, const char *layer,
                          const char *pass);
/* 1 when every channel of the pass was read as 8/16-bit integers (PNG,
 * JPEG, integer TIFF): its values are already display-encoded, not scene
 * linear. 0 otherwise (floats, new channels, no such pass). */
int ewio_pass_read_as_integer(const ewio_file *f, const char *layer, const char *pass);

/* Write `len` bytes of text (a report, a CSV) on the same atomic path as
 * ewio_write: a temporary beside `path`, flushed, renamed over it; on any
 * failure (a full disk) `path` is left as it was — never empty or cut
 * short — and the temporary is removed. Refuses a directory or a
 * non-regular file (a FIFO, a device) at `path`. */
int ewio_write_text(const char *path, const char *text, size_t len, char *err, size_t errlen);

/* Remove every temporary that a write in this process is filling now.
 * Async-signal-safe: for a SIGINT/SIGTERM handler, which then ends the
 * process (the CLI exits 128 + the signal number). A process killed
 * outright (SIGKILL, power loss) leaves its temporary behind: a hidden
 * ".<name>.tmp-XXXXXX.<ext>" beside the output, safe to delete when no
 * edgewise run writes there. */
void ewio_remove_temporaries(void);

/* Create an empty in-memory file of the given size (for tests and for
 * writing library outputs that did not come from a file): no channels, no
 * metadata; written as EXR it gets zip compression. Same size limits as
 * ewio_read. */
int ewio_create(int width, int height, ewio_file **out, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif

#endif /* EDGEWISE_EWIO_H */
