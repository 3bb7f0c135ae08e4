/*
 * exr_zip_writer.cpp — EXR parts of ZIP or ZIPS compression whose chunks
 * are deflated here, with libdeflate (exr_zip.h).
 *
 * Why not through OpenEXR: Debian 12's OpenEXR (3.1) deflates with zlib,
 * which took 6.0 s of one core for the 23 channels of a denoised 3840x2160
 * multilayer frame, more than reading and denoising it; libdeflate at the
 * same level took 2.4 s for a file 2 % smaller (OpenEXR itself moved to
 * libdeflate in 3.2, for this). ZIP is the compression Blender and
 * OpenImageIO write by default, so most outputs come through here.
 *
 * The header is OpenEXR's (Imf::Header::writeTo, the bytes Imf::OutputFile
 * writes for it). What is written here is the layout around it, as the
 * file format's specification gives it: the magic number and the version
 * field, the chunk table (an offset a chunk, filled in on close), and each
 * chunk as the y of its first row, its size and its data. ZIP's data of a
 * chunk (16 rows; ZIPS: 1): the rows in the file's layout (a row holds
 * every channel's values in turn, channels in the header's order,
 * little-endian), its bytes split into the even-indexed then the odd-indexed
 * ones, each byte replaced by its difference from the one before plus 128,
 * and that deflated in zlib's format; stored as it is where that is not
 * smaller, as OpenEXR does and its readers expect.
 */
#include "exr_zip.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfThreading.h>

#include <libdeflate.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <stdexcept>
#include <vector>

namespace ewio {
namespace {

const int32_t kMagic = 20000630;
const int32_t kVersion = 2;
const int32_t kLongNames = 0x400; /* a name or type name of 32 bytes or more */

std::runtime_error io_error(const char *what, const std::string &path) {
    return std::runtime_error(std::string(what) + " " + path + " failed: " + std::strerror(errno));
}

/* The header's bytes go through this onto the file. */
class FileOStream final : public Imf::OStream {
  public:
    FileOStream(FILE *f, const std::string &path) : Imf::OStream(path.c_str()), f_(f), path_(path) {}
    void write(const char c[], int n) override {
        if (std::fwrite(c, 1, size_t(n), f_) != size_t(n)) throw io_error("writing", path_);
    }
    uint64_t tellp() override {
        const off_t p = ftello(f_);
        if (p < 0) throw io_error("writing", path_);
        return uint64_t(p);
    }
    void seekp(uint64_t pos) override {
        if (fseeko(f_, off_t(pos), SEEK_SET) != 0) throw io_error("writing", path_);
    }

  private:
    FILE *f_;
    std::string path_;
};

/* as OpenEXR decides it (usesLongNames, not in its public headers) */
bool long_names(const Imf::Header &h) {
    for (Imf::Header::ConstIterator i = h.begin(); i != h.end(); ++i)
        if (std::strlen(i.name()) >= 32 || std::strlen(i.attribute().typeName()) >= 32) return true;
    for (Imf::ChannelList::ConstIterator i = h.channels().begin(); i != h.channels().end(); ++i)
        if (std::strlen(i.name()) >= 32) return true;
    return false;
}

template <class T> void put_le(std::vector<unsigned char> &b, T v) {
    unsigned char c[sizeof(T)];
    std::memcpy(c, &v, sizeof(T)); /* the machine is little-endian, as the file */
    b.insert(b.end(), c, c + sizeof(T));
}

/* A channel of the file, in the file's order. */
struct Chan {
    size_t src;   /* its index among the band's channels (spec.names) */
    PixType type;
    size_t bytes; /* of one value */
};

struct FreeDeflater {
    void operator()(libdeflate_compressor *c) const { libdeflate_free_compressor(c); }
};

/* What one chunk needs while it is packed and deflated on a thread. */
struct Slot {
    std::vector<unsigned char> raw, tmp, out;
    std::vector<float> line;    /* one channel's row, gathered */
    std::vector<uint32_t> conv; /* ... converted */
    std::unique_ptr<libdeflate_compressor, FreeDeflater> deflater;
    const BandSrc *band = nullptr; /* the band holding the chunk's rows, or null: raw holds them packed */
    size_t band_row = 0;           /* the chunk's first row in it */
    int first = 0, rows = 0;       /* rows from the data window's top */
    const unsigned char *data = nullptr;
    size_t size = 0;
};

} // namespace

struct ZipPartWriter::Impl {
    FILE *f = nullptr;
    std::string path;
    int width = 0, height = 0, top = 0, lines = 16, level = 4;
    size_t line_bytes = 0;
    std::vector<Chan> chans;
    std::vector<uint64_t> offsets;
    uint64_t table_at = 0;
    int done = 0;       /* rows handed to write() so far */
    Slot carry;         /* the chunk begun by one band and ended by a later one */
    std::vector<std::unique_ptr<Slot>> slots;

    ~Impl() {
        if (f) std::fclose(f);
    }

    /* row r of the band in the file's layout at dst */
    void pack_row(Slot &s, const BandSrc *band, size_t r, unsigned char *dst) const {
        const size_t w = size_t(width);
        s.line.resize(w);
        s.conv.resize(w);
        for (const Chan &c : chans) {
            const float *v = band[c.src].row(r, w, s.line.data());
            const void *from = v;
            if (c.type == PixType::HALF) {
                to_half(v, reinterpret_cast<uint16_t *>(s.conv.data()), w);
                from = s.conv.data();
            } else if (c.type == PixType::U32) {
                to_uint(v, s.conv.data(), w);
                from = s.conv.data();
            }
            std::memcpy(dst, from, w * c.bytes);
            dst += w * c.bytes;
        }
    }

    /* s's rows packed (unless they are already) and deflated into s.data / s.size */
    void encode(Slot &s) const {
        const size_t n = size_t(s.rows) * line_bytes;
        s.raw.resize(std::max(s.raw.size(), n));
        if (s.band)
            for (int r = 0; r < s.rows; r++) pack_row(s, s.band, s.band_row + size_t(r), s.raw.data() + size_t(r) * line_bytes);
        s.tmp.resize(std::max(s.tmp.size(), n));
        s.out.resize(std::max(s.out.size(), n));
        const unsigned char *raw = s.raw.data();
        unsigned char *t = s.tmp.data();
        zip_split(raw, n, t);
        zip_predict(t, n);
        if (!s.deflater) s.deflater.reset(libdeflate_alloc_compressor(level));
        if (!s.deflater) throw std::bad_alloc();
        /* 0 when it does not fit in fewer bytes than the rows themselves */
        const size_t got = n > 1 ? libdeflate_zlib_compress(s.deflater.get(), t, n, s.out.data(), n - 1) : 0;
        s.data = got ? s.out.data() : raw;
        s.size = got ? got : n;
    }

    void put_chunk(const Slot &s) {
        const off_t at = ftello(f);
        if (at < 0) throw io_error("writing", path);
        offsets[size_t(s.first / lines)] = uint64_t(at);
        std::vector<unsigned char> head;
        put_le<int32_t>(head, int32_t(top + s.first));
        put_le<int32_t>(head, int32_t(s.size));
        if (std::fwrite(head.data(), 1, head.size(), f) != head.size() || std::fwrite(s.data, 1, s.size, f) != s.size)
            throw io_error("writing", path);
    }

    /* the chunks in slots[0..k) encoded on the pool's threads, then written in order */
    void run(size_t k) {
        run_on_pool(k, [this](size_t i) { encode(*slots[i]); });
        for (size_t i = 0; i < k; i++) put_chunk(*slots[i]);
    }
};

ZipPartWriter::ZipPartWriter() : d_(new Impl) {}
ZipPartWriter::~ZipPartWriter() = default;

void ZipPartWriter::open(const std::string &path, const Imf::Header &h, const WriteSpec &spec) {
    Impl &d = *d_;
    h.sanityCheck();
    const Imath::Box2i dw = h.dataWindow();
    d.path = path;
    d.width = dw.max.x - dw.min.x + 1;
    d.height = dw.max.y - dw.min.y + 1;
    d.top = dw.min.y;
    d.lines = zip_lines(h.compression());
    d.level = std::min(std::max(h.zipCompressionLevel(), 0), 12);
    std::map<std::string, size_t> index;
    for (size_t i = 0; i < spec.names.size(); i++) index[spec.names[i]] = i;
    for (Imf::ChannelList::ConstIterator i = h.channels().begin(); i != h.channels().end(); ++i) {
        const auto at = index.find(i.name());
        if (at == index.end()) throw std::runtime_error(std::string("no values for channel ") + i.name());
        const PixType t = spec.types[at->second];
        d.chans.push_back(Chan{at->second, t, t == PixType::HALF ? size_t(2) : size_t(4)});
        d.line_bytes += size_t(d.width) * d.chans.back().bytes;
    }
    d.offsets.assign(size_t((d.height + d.lines - 1) / d.lines), 0);
    const int threads = std::max(1, Imf::globalThreadCount());
    for (int i = 0; i < threads; i++) d.slots.emplace_back(new Slot);
    d.f = std::fopen(path.c_str(), "wb");
    if (!d.f) throw io_error("creating", path);
    FileOStream os(d.f, path);
    std::vector<unsigned char> head;
    put_le<int32_t>(head, kMagic);
    put_le<int32_t>(head, kVersion | (long_names(h) ? kLongNames : 0));
    os.write(reinterpret_cast<const char *>(head.data()), int(head.size()));
    h.writeTo(os);
    d.table_at = os.tellp();
    const std::vector<char> table(d.offsets.size() * sizeof(uint64_t), 0);
    os.write(table.data(), int(table.size()));
}

void ZipPartWriter::write(int y0, int y1, const BandSrc *src) {
    Impl &d = *d_;
    if (y0 != d.done || y1 <= y0 || y1 > d.height) throw std::runtime_error("rows written out of order");
    int y = y0;
    size_t k = 0;
    /* the chunk an earlier band began: its rows packed as they come */
    if (d.carry.rows > 0) {
        const int end = std::min(d.carry.first + d.lines, d.height), take = std::min(end, y1) - y;
        d.carry.raw.resize(size_t(end - d.carry.first) * d.line_bytes);
        for (int r = 0; r < take; r++)
            d.pack_row(d.carry, src, size_t(y - y0 + r), d.carry.raw.data() + size_t(d.carry.rows + r) * d.line_bytes);
        d.carry.rows += take;
        y += take;
        if (d.carry.first + d.carry.rows == end) {
            std::swap(*d.slots[k++], d.carry); /* slot 0 takes it packed, carry gets slot 0's buffers */
            d.carry.rows = 0;
            if (k == d.slots.size()) {
                d.run(k);
                k = 0;
            }
        }
    }
    while (y < y1) {
        const int end = std::min(y + d.lines, d.height); /* y starts a chunk here */
        if (end > y1) break;                              /* ends in a later band */
        Slot &s = *d.slots[k++];
        s.band = src;
        s.band_row = size_t(y - y0);
        s.first = y;
        s.rows = end - y;
        y = end;
        if (k == d.slots.size()) {
            d.run(k);
            k = 0;
        }
    }
    if (k) d.run(k);
    for (auto &s : d.slots) s->band = nullptr;
    if (y < y1) { /* the start of a chunk the next band ends */
        d.carry.band = nullptr;
        d.carry.first = y;
        d.carry.rows = y1 - y;
        d.carry.raw.resize(size_t(std::min(y + d.lines, d.height) - y) * d.line_bytes);
        for (int r = 0; r < d.carry.rows; r++)
            d.pack_row(d.carry, src, size_t(y - y0 + r), d.carry.raw.data() + size_t(r) * d.line_bytes);
    }
    d.done = y1;
}

void ZipPartWriter::close() {
    Impl &d = *d_;
    if (d.done != d.height)
        throw std::runtime_error("only " + std::to_string(d.done) + " of " + std::to_string(d.height) +
                                 " rows were written");
    FileOStream os(d.f, d.path);
    os.seekp(d.table_at);
    std::vector<unsigned char> table;
    for (uint64_t o : d.offsets) put_le<uint64_t>(table, o);
    os.write(reinterpret_cast<const char *>(table.data()), int(table.size()));
    FILE *f = d.f;
    d.f = nullptr;
    const bool flushed = std::fflush(f) == 0;
    if (std::fclose(f) != 0 || !flushed) throw io_error("closing", d.path);
}

} // namespace ewio
