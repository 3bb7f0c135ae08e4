/*
 * exr_zip_reader.cpp — rows of ZIP and ZIPS scanline parts decoded with
 * libdeflate (exr_zip.h).
 *
 * Why not through OpenEXR: Debian 12's OpenEXR (3.1) inflates with zlib,
 * and then copies every row through a line buffer of its own; a one-shot
 * denoise of a 3840x2160 multilayer frame spent 2.9 s of CPU in zlib and
 * 2.9 s in OpenEXR's decoding, twice its compute (the passes it does not
 * denoise are decoded again on writing, to be copied into the output).
 * OpenEXR still reads the chunk from the file (rawPixelDataToBuffer, which
 * checks its place, its y and its size against the part), so what is done
 * here is ZIP's undoing (exr_zip_writer.cpp describes the encoding) and the
 * conversion to float, each chunk on one of the pool's threads.
 */
#include "exr_zip.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfThreading.h>

#include <libdeflate.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <stdexcept>
#include <vector>

namespace ewio {
namespace {

struct FreeInflater {
    void operator()(libdeflate_decompressor *d) const { libdeflate_free_decompressor(d); }
};

/* A channel's place in a row of the file. */
struct Place {
    size_t at;    /* bytes from the row's start */
    Imf::PixelType type;
};

/* Bytes for a chunk, freed when a pass ends. From the heap, so that the
 * next pass — in a graph, the next frame's — reuses them where the program
 * keeps freed memory (the CLI does) instead of faulting in new pages; taken
 * on the reading thread (ZipPartReader::read), not the pool's, so that they
 * come from the main arena, whose free memory malloc_trim hands back (a
 * pool thread's arena keeps what is freed at its top whatever the trim):
 * a one-shot command trims the heap before its method runs, so they are
 * not held beside the frame. Uninitialised: every byte read is written
 * first. */
class Pages {
  public:
    unsigned char *get() const { return p_.get(); }
    void reserve(size_t n) {
        if (n <= n_) return;
        p_.reset();
        p_.reset(new unsigned char[n]);
        n_ = n;
    }
    void release() {
        p_.reset();
        n_ = 0;
    }

  private:
    std::unique_ptr<unsigned char[]> p_;
    size_t n_ = 0;
};

/* What one chunk needs while it is read and decoded on a thread. */
struct Slot {
    Pages packed, tmp;
    std::vector<float> line;      /* one channel's row as float, for a destination with gaps */
    std::vector<uint16_t> halves; /* ... as the file's halves, or the halves of its uints */
    std::unique_ptr<libdeflate_decompressor, FreeInflater> inflater;
    int first = 0; /* the chunk's first row, from the data window's top */
};

/* A chunk's rows in the file's layout: as stored (plain), or inflated and
 * its differences summed, still split (byte i of the rows is lo[i / 2] for
 * an even i, hi[i / 2] for an odd one). */
struct Rows {
    const unsigned char *plain, *lo, *hi;
    /* the rows' bytes at..at+len-1 (both even: a channel's row) into to */
    void get(size_t at, size_t len, unsigned char *to) const {
        if (plain)
            std::memcpy(to, plain + at, len);
        else
            zip_merge(lo + at / 2, hi + at / 2, len / 2, to);
    }
};

} // namespace

struct ZipPartReader::Impl {
    Imf::InputPart *in = nullptr;
    int width = 0, height = 0, top = 0, lines = 16;
    size_t line_bytes = 0;
    std::map<std::string, Place> places;
    std::vector<std::unique_ptr<Slot>> slots;

    /* The bytes a chunk's data may take as OpenEXR reads it: it accepts a
     * chunk of up to a whole chunk's rows of bytes (all `lines` of them,
     * the part's last and shorter chunk too, and a part shorter than one
     * chunk) and writes it into the buffer it is given without asking its
     * size, so every buffer is that large. */
    size_t chunk_bytes() const { return size_t(lines) * line_bytes; }

    /* the chunk of s's first row, n bytes of rows */
    Rows inflate(Slot &s, size_t n) const {
        int size = int(chunk_bytes()); /* in: the buffer's size; out: the chunk's */
        in->rawPixelDataToBuffer(top + s.first, reinterpret_cast<char *>(s.packed.get()), size);
        if (size < 0 || size_t(size) > chunk_bytes())
            throw std::runtime_error("the chunk of row " + std::to_string(top + s.first) + " declares " +
                                     std::to_string(size) + " bytes (damaged data)");
        if (size_t(size) == n) return Rows{s.packed.get(), nullptr, nullptr}; /* stored as it is */
        if (!s.inflater) s.inflater.reset(libdeflate_alloc_decompressor());
        if (!s.inflater) throw std::bad_alloc();
        size_t got = 0;
        unsigned char *t = s.tmp.get();
        if (libdeflate_zlib_decompress(s.inflater.get(), s.packed.get(), size_t(size), t, n, &got) != LIBDEFLATE_SUCCESS ||
            got != n)
            throw std::runtime_error("the chunk of row " + std::to_string(top + s.first) + " does not inflate to its " +
                                     std::to_string(n) + " bytes (damaged data)");
        zip_unpredict(t, n);
        return Rows{nullptr, t, t + (n + 1) / 2};
    }

    /* rows y0..y1-1 of the band that lie in s's chunk, every asked channel */
    void decode(Slot &s, int y0, int y1, const Place *const *at, const BandDst *dst, size_t nd) const {
        const int rows = std::min(lines, height - s.first);
        const Rows r = inflate(s, size_t(rows) * line_bytes);
        const size_t w = size_t(width);
        s.line.resize(w);
        s.halves.resize(2 * w);
        unsigned char *bytes = reinterpret_cast<unsigned char *>(s.halves.data());
        for (int y = std::max(y0, s.first); y < std::min(y1, s.first + rows); y++) {
            const size_t row = size_t(y - s.first) * line_bytes;
            for (size_t k = 0; k < nd; k++) {
                const size_t v = row + at[k]->at;
                float *o = dst[k].p + size_t(y - y0) * dst[k].ys;
                /* converted straight into a packed destination */
                float *f = dst[k].xs == 1 ? o : s.line.data();
                if (at[k]->type == Imf::HALF) {
                    r.get(v, 2 * w, bytes);
                    half_to_float(s.halves.data(), f, w);
                } else if (at[k]->type == Imf::UINT) {
                    r.get(v, 4 * w, bytes);
                    for (size_t x = 0; x < w; x++) {
                        uint32_t u;
                        std::memcpy(&u, bytes + 4 * x, 4);
                        f[x] = float(u);
                    }
                } else {
                    r.get(v, 4 * w, reinterpret_cast<unsigned char *>(f));
                }
                if (dst[k].xs != 1)
                    for (size_t x = 0; x < w; x++) o[x * dst[k].xs] = f[x];
            }
        }
    }
};

ZipPartReader::ZipPartReader(Imf::InputPart &in, const Imf::Header &h) : d_(new Impl) {
    Impl &d = *d_;
    const Imath::Box2i dw = h.dataWindow();
    d.in = &in;
    d.width = dw.max.x - dw.min.x + 1;
    d.height = dw.max.y - dw.min.y + 1;
    d.top = dw.min.y;
    d.lines = zip_lines(h.compression());
    for (Imf::ChannelList::ConstIterator c = h.channels().begin(); c != h.channels().end(); ++c) {
        d.places[c.name()] = Place{d.line_bytes, c.channel().type};
        d.line_bytes += size_t(d.width) * (c.channel().type == Imf::HALF ? 2 : 4);
    }
    const int threads = std::max(1, Imf::globalThreadCount());
    for (int i = 0; i < threads; i++) d.slots.emplace_back(new Slot);
}

ZipPartReader::~ZipPartReader() = default;

void ZipPartReader::read(int y0, int y1, const std::string *names, const BandDst *dst, size_t n) {
    Impl &d = *d_;
    std::vector<const Place *> at(n);
    for (size_t k = 0; k < n; k++) {
        const auto p = d.places.find(names[k]);
        if (p == d.places.end()) throw std::runtime_error("no channel " + names[k]);
        at[k] = &p->second;
    }
    /* here, not on the pool's threads (see Pages) */
    for (auto &s : d.slots) {
        s->packed.reserve(d.chunk_bytes());
        s->tmp.reserve(d.chunk_bytes());
    }
    for (int first = y0 - y0 % d.lines; first < y1;) {
        size_t k = 0;
        for (; k < d.slots.size() && first < y1; k++, first += d.lines) d.slots[k]->first = first;
        run_on_pool(k, [&](size_t i) { d.decode(*d.slots[i], y0, y1, at.data(), dst, n); });
    }
    /* reads go down the part, and one that reached its end is the last of
     * a pass (the next, if any, passes by later: the written file's
     * passes it copies); the chunk buffers are not held in between */
    if (y1 == d.height)
        for (auto &s : d.slots) {
            s->packed.release();
            s->tmp.release();
        }
}

} // namespace ewio
