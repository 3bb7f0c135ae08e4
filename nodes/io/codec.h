/*
 * codec.h — what ewio.cpp asks of a file format (internal to nodes/io).
 *
 * ewio.cpp holds the image (channels, layers, metadata) and does everything
 * around a file — limits, naming, temporaries, checks, the atomic rename —
 * and a codec only decodes and encodes pixels and headers:
 *   - exr_codec.cpp: OpenEXR, linked in, for every EXR file;
 *   - oiio_codec.cpp: OpenImageIO, for PNG, TIFF, JPEG and anything else it
 *     reads, built as the module libedgewise_oiio.so and loaded the first time
 *     such a file is met (oiio_module.cpp): OpenImageIO and its ~260 libraries
 *     cost ~0.4 s and ~120 MB of every process that loads them, which a run
 *     on EXR files alone never needs.
 * Metadata travels as OpenEXR stores it (a type name and the value's bytes),
 * so an EXR's attributes are written back bit for bit, whatever their type.
 */
#ifndef EDGEWISE_IO_CODEC_H
#define EDGEWISE_IO_CODEC_H

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <utility>
#include <vector>

namespace ewio {

/* The type a channel is stored with. */
enum class PixType : unsigned char { U8, I8, U16, I16, U32, I32, HALF, FLOAT, DOUBLE };

/* Pixels are moved between a codec and ewio's planes in bands of rows of
 * about this many floats, so no second whole-image copy is ever held. */
constexpr size_t kBandFloats = size_t(2) << 20;

/* Rows of a band of `row_bytes` bytes a row, of an image `h` rows high:
 * about kBandFloats floats, in whole 32-row chunks (a zip chunk is 16
 * rows, a piz one 32): a chunk is decoded once, not once for each band it
 * straddles, and every call hands OpenEXR whole chunks to work on in
 * parallel. One chunk where the rows are wider than that, unless a chunk
 * is far above the band's size (thousands of channels): then at least a row. */
inline size_t band_rows_of(size_t row_bytes, size_t h) {
    const size_t band = kBandFloats * sizeof(float);
    size_t rows = band / std::max<size_t>(row_bytes, 1);
    if (rows >= 32)
        rows -= rows % 32;
    else if (32 * row_bytes <= 8 * band)
        rows = 32;
    else
        rows = std::max<size_t>(rows, 1);
    return std::min(rows, std::max<size_t>(h, 1));
}

/* What a written file turned out to be, where it is not what was written. */
inline std::string reads_as(long long w, long long h, long long nch) {
    return "it reads as " + std::to_string(w) + "x" + std::to_string(h) + " with " + std::to_string(nch) +
           " channels";
}

/* One header attribute as OpenEXR writes it: its type name ("string",
 * "int", "float", "v2f", "m44f", "chromaticities", ...) and its value's
 * bytes (little-endian; a string's bytes without terminator). */
struct Attr {
    std::string name, type;
    std::string value;
};

inline Attr attr_string(const std::string &name, const std::string &v) { return Attr{name, "string", v}; }
inline Attr attr_int(const std::string &name, int32_t v) {
    Attr a{name, "int", std::string(4, '\0')};
    for (int i = 0; i < 4; i++) a.value[size_t(i)] = char((uint32_t(v) >> (8 * i)) & 0xff);
    return a;
}
inline Attr attr_float(const std::string &name, float v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    Attr a{name, "float", std::string(4, '\0')};
    for (int i = 0; i < 4; i++) a.value[size_t(i)] = char((u >> (8 * i)) & 0xff);
    return a;
}

/* The attribute's value as text: a string as it is, numbers (and vectors,
 * boxes, matrices of them) in their shortest exact form joined by ", ";
 * "" for types without a plain reading (previews, opaque data). */
std::string attr_text(const Attr &a);

/* One part (subimage) of a file, from its header. */
struct PartHeader {
    long long width = 0, height = 0;
    int x = 0, y = 0, full_x = 0, full_y = 0;
    long long full_width = 0, full_height = 0;
    bool deep = false, volume = false;
    /* tiled: the codec reads the part in one band (the whole image) */
    bool tiled = false;
    /* rows can be decoded band by band later, from the file (scanline EXR) */
    bool decodes_later = false;
    std::string name;      /* the part's name ("" if none) */
    std::string problem;   /* non-empty: why its channels cannot be read */
    std::vector<std::string> channels;
    std::vector<PixType> types;
};

/* Where a channel's band goes: the band's first value (its top row's first
 * pixel), `xs` floats between a row's values and `ys` between rows. */
struct BandDst {
    float *p;
    size_t xs, ys;
};

/* Where a channel's band comes from, laid out as BandDst. */
struct BandSrc {
    const float *p;
    size_t xs, ys;
    /* the value of row y, column x */
    float at(size_t y, size_t x) const { return p[y * ys + x * xs]; }
    /* row y's w values packed: where they are when xs is 1, else gathered
     * into tmp (w floats) */
    const float *row(size_t y, size_t w, float *tmp) const {
        if (xs == 1) return p + y * ys;
        for (size_t x = 0; x < w; x++) tmp[x] = at(y, x);
        return tmp;
    }
};

class Reader {
  public:
    virtual ~Reader() = default;
    virtual const std::vector<PartHeader> &parts() const = 0;
    /* The first part's metadata, less what describes the file's layout
     * (channels, windows, chunks, compression, tiles, part names). */
    virtual std::vector<Attr> attributes() const = 0;
    /* The first part's compression by name ("zip", "piz"...), "" if not EXR. */
    virtual std::string compression() const { return std::string(); }
    /* Rows y0..y1-1 (0 = the data window's top) of channels chans[0..n) of
     * part `part`, converted to float, into dst[k]. false with a reason. */
    virtual bool read(int part, int y0, int y1, const int *chans, const BandDst *dst, size_t n,
                      std::string &why) = 0;
};

/* What to write: one part, channels in this order. */
struct WriteSpec {
    int width = 0, height = 0, x = 0, y = 0, full_x = 0, full_y = 0, full_width = 0, full_height = 0;
    std::vector<std::string> names;
    std::vector<PixType> types;
    std::vector<Attr> attrs;
    std::string compression; /* EXR: "" = zip */
};

class Writer {
  public:
    virtual ~Writer() = default;
    /* Create `path` (which exists, empty) for spec. */
    virtual bool open(const std::string &path, const WriteSpec &spec, std::string &why) = 0;
    /* The next rows y0..y1-1, channel c of spec.names from src[c]. */
    virtual bool write(int y0, int y1, const BandSrc *src, std::string &why) = 0;
    virtual bool close(std::string &why) = 0;
};

/* A codec's entry points. */
struct Codec {
    /* nullptr with a reason when the file is not one this codec reads */
    std::unique_ptr<Reader> (*open_reader)(const std::string &path, std::string &why);
    /* a writer; the format follows the path given to its open() */
    std::unique_ptr<Writer> (*create_writer)();
    /* Whether `path` opens as a w x h image with nch channels whose pixels
     * all decode (in bands: little memory). */
    bool (*read_back)(const std::string &path, long long w, long long h, long long nch, std::string &why);
    /* Threads that decode and encode (> 0). */
    void (*set_threads)(int n);
};

const Codec &exr_codec();

/* The OpenImageIO codec, loaded on first use; nullptr with a reason when
 * its module cannot be loaded. Thread-safe. */
const Codec *oiio_codec(std::string &why);

/* The OpenImageIO codec if it is loaded already, else nullptr (never loads it). */
const Codec *oiio_codec_loaded();

/* The threads every codec uses (ewio_set_threads; > 0), applied to the
 * OpenImageIO codec when it is loaded later. */
int io_threads();

/* One line: newlines become "; ", trailing blanks dropped. */
inline std::string one_line(const std::string &s) {
    std::string o;
    o.reserve(s.size());
    for (char c : s) {
        if (c == '\n' || c == '\r') {
            while (!o.empty() && (o.back() == ' ' || o.back() == '\t')) o.pop_back();
            if (!o.empty() && o.back() != ' ' && o.back() != ';') o += "; ";
        } else {
            o += c;
        }
    }
    while (!o.empty() && (o.back() == ' ' || o.back() == ';' || o.back() == '\t')) o.pop_back();
    return o;
}

/* The first non-empty line of a library's message (write errors can repeat
 * per block), or `fallback` when there is none. */
inline std::string first_line(const std::string &s, const char *fallback = "") {
    size_t b = 0;
    while (b < s.size()) {
        size_t e = s.find('\n', b);
        if (e == std::string::npos) e = s.size();
        std::string line = one_line(s.substr(b, e - b));
        if (!line.empty()) return line;
        b = e + 1;
    }
    return fallback;
}

} // namespace ewio

/* The module's one symbol (oiio_codec.cpp). */
extern "C" const ewio::Codec *ewio_oiio_codec(void);

#endif /* EDGEWISE_IO_CODEC_H */
