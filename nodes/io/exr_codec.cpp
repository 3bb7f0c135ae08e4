/*
 * exr_codec.cpp — OpenEXR files through OpenEXR's own library (codec.h).
 *
 * Reads every part's header, decodes bands of rows of chosen channels
 * straight into ewio's planes (OpenEXR converts half and uint to float and
 * writes with any strides, so no band buffer is needed), and writes one
 * scanline part from bands of interleaved floats. Parts of ZIP or ZIPS
 * compression have their chunks inflated and deflated in exr_zip_reader.cpp
 * and exr_zip_writer.cpp (exr_zip.h says why). Exceptions stay inside:
 * every entry point turns them into a reason.
 */
#include "codec.h"
#include "exr_zip.h"

#include <OpenEXR/IlmThreadPool.h>
#include <OpenEXR/ImfAttribute.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfOpaqueAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfThreading.h>
#include <Imath/half.h>

#include <cpuid.h>
#include <immintrin.h>

#include <charconv>
#include <exception>
#include <cstdio>
#include <mutex>
#include <strings.h>

namespace ewio {
namespace {

/* ------------------------------------------------------------ threads */

std::once_flag g_pool_once;

/* OpenEXR's pool has no threads until told (0 = decode in the caller's
 * thread): every use goes through here first, with ewio's count (the
 * machine's unless ewio_set_threads said otherwise). */
void ensure_pool() {
    std::call_once(g_pool_once, [] { Imf::setGlobalThreadCount(io_threads()); });
}

void exr_set_threads(int n) {
    std::call_once(g_pool_once, [] {});
    Imf::setGlobalThreadCount(n);
}

} // namespace

void run_on_pool(size_t k, const std::function<void(size_t)> &job) {
    struct Task final : IlmThread::Task {
        Task(IlmThread::TaskGroup *g, const std::function<void(size_t)> &job, size_t i, std::exception_ptr &failed)
            : IlmThread::Task(g), job_(job), i_(i), failed_(failed) {}
        void execute() override {
            try {
                job_(i_);
            } catch (...) {
                failed_ = std::current_exception();
            }
        }
        const std::function<void(size_t)> &job_;
        size_t i_;
        std::exception_ptr &failed_;
    };
    std::vector<std::exception_ptr> failed(k);
    {
        IlmThread::TaskGroup group; /* its destructor waits for the tasks */
        for (size_t i = 0; i < k; i++) IlmThread::ThreadPool::addGlobalTask(new Task(&group, job, i, failed[i]));
    }
    for (const std::exception_ptr &e : failed)
        if (e) std::rethrow_exception(e);
}

namespace {

/* ------------------------------------------------------- attributes */

/* An attribute's bytes, as OpenEXR writes them into a header. */
class StringOStream final : public Imf::OStream {
  public:
    StringOStream() : Imf::OStream("attribute") {}
    void write(const char c[], int n) override {
        if (pos_ + size_t(n) > s_.size()) s_.resize(pos_ + size_t(n));
        std::memcpy(&s_[pos_], c, size_t(n));
        pos_ += size_t(n);
    }
    uint64_t tellp() override { return pos_; }
    void seekp(uint64_t pos) override { pos_ = size_t(pos); }
    std::string s_;

  private:
    size_t pos_ = 0;
};

class StringIStream final : public Imf::IStream {
  public:
    explicit StringIStream(const std::string &s) : Imf::IStream("attribute"), s_(s) {}
    bool read(char c[], int n) override {
        if (pos_ + size_t(n) > s_.size()) throw std::runtime_error("attribute value cut short");
        std::memcpy(c, s_.data() + pos_, size_t(n));
        pos_ += size_t(n);
        return pos_ < s_.size();
    }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override { pos_ = size_t(pos); }
    void clear() override {}

  private:
    const std::string &s_;
    size_t pos_ = 0;
};

/* What describes the file's layout rather than the image: the output is
 * one scanline part whose writer sets these itself. */
bool layout_attr(const std::string &n) {
    static const char *const names[] = {"channels",  "compression", "dataWindow", "displayWindow",
                                        "lineOrder", "tiles",       "type",       "name",
                                        "version",   "chunkCount",  "maxSamplesPerPixel"};
    for (const char *k : names)
        if (n == k) return true;
    return false;
}

std::unique_ptr<Imf::Attribute> make_attribute(const Attr &a) {
    std::unique_ptr<Imf::Attribute> at;
    if (Imf::Attribute::knownType(a.type.c_str()))
        at.reset(Imf::Attribute::newAttribute(a.type.c_str()));
    else
        at.reset(new Imf::OpaqueAttribute(a.type.c_str()));
    StringIStream is(a.value);
    at->readValueFrom(is, int(a.value.size()), 2);
    return at;
}

/* ---------------------------------------------------- compression names */

struct CompName {
    const char *name;
    Imf::Compression c;
};
const CompName kComp[] = {{"none", Imf::NO_COMPRESSION},   {"rle", Imf::RLE_COMPRESSION},
                          {"zips", Imf::ZIPS_COMPRESSION}, {"zip", Imf::ZIP_COMPRESSION},
                          {"piz", Imf::PIZ_COMPRESSION},   {"pxr24", Imf::PXR24_COMPRESSION},
                          {"b44", Imf::B44_COMPRESSION},   {"b44a", Imf::B44A_COMPRESSION},
                          {"dwaa", Imf::DWAA_COMPRESSION}, {"dwab", Imf::DWAB_COMPRESSION}};

std::string comp_name(Imf::Compression c) {
    for (const CompName &k : kComp)
        if (k.c == c) return k.name;
    return "zip";
}

/* "zip", "dwaa:45" (a level after the colon, as OpenImageIO spells it) */
bool parse_comp(const std::string &s, Imf::Compression *c, float *level) {
    const size_t colon = s.find(':');
    const std::string n = s.substr(0, colon);
    *level = -1.0f;
    if (colon != std::string::npos) {
        const char *b = s.c_str() + colon + 1;
        char *end = nullptr;
        *level = std::strtof(b, &end);
        if (end == b || *end) *level = -1.0f;
    }
    for (const CompName &k : kComp)
        if (strcasecmp(n.c_str(), k.name) == 0) {
            *c = k.c;
            return true;
        }
    return false;
}

PixType pix_type(Imf::PixelType t) {
    return t == Imf::HALF ? PixType::HALF : t == Imf::UINT ? PixType::U32 : PixType::FLOAT;
}

/* --------------------------------------------------------------- read */

/* OpenEXR lists channels by name; they are ordered as OpenImageIO orders
 * them (and ewio always has): by layer, then the reserved names in this
 * order (R, Red, G... case-insensitive) before the layer's other channels,
 * then by name. */
int special_index(const std::string &suffix) {
    static const char *const special[] = {"R",    "Red", "G",  "Green", "B",  "Blue", "X",
                                          "Y",    "Z",   "real", "imag", "A", "Alpha", "AR",
                                          "RA",   "AG",  "GA", "AB",    "BA", "Depth", "Zback"};
    for (size_t i = 0; i < sizeof special / sizeof *special; i++)
        if (strcasecmp(suffix.c_str(), special[i]) == 0) return int(i);
    return 10000;
}

struct Chan {
    std::string name, layer, suffix;
    int special;
    Imf::PixelType type;
};

void order_channels(std::vector<Chan> &v) {
    for (Chan &c : v) {
        const size_t dot = c.name.rfind('.');
        c.layer = dot == std::string::npos ? std::string() : c.name.substr(0, dot + 1);
        c.suffix = dot == std::string::npos ? c.name : c.name.substr(dot + 1);
        c.special = special_index(c.suffix);
    }
    std::stable_sort(v.begin(), v.end(), [](const Chan &a, const Chan &b) {
        if (a.layer != b.layer) return a.layer < b.layer;
        if (a.special != b.special) return a.special < b.special;
        return a.suffix < b.suffix;
    });
}

class ExrReader final : public Reader {
  public:
    explicit ExrReader(const std::string &path) {
        ensure_pool();
        file_.reset(new Imf::MultiPartInputFile(path.c_str(), Imf::globalThreadCount()));
        const int n = file_->parts();
        in_.resize(size_t(n));
        zip_.resize(size_t(n));
        for (int i = 0; i < n; i++) {
            const Imf::Header &h = file_->header(i);
            PartHeader ph;
            const Imath::Box2i dw = h.dataWindow(), disp = h.displayWindow();
            ph.width = (long long)dw.max.x - dw.min.x + 1;
            ph.height = (long long)dw.max.y - dw.min.y + 1;
            ph.x = dw.min.x;
            ph.y = dw.min.y;
            ph.full_x = disp.min.x;
            ph.full_y = disp.min.y;
            ph.full_width = (long long)disp.max.x - disp.min.x + 1;
            ph.full_height = (long long)disp.max.y - disp.min.y + 1;
            ph.deep = h.hasType() && Imf::isDeepData(h.type());
            ph.tiled = h.hasTileDescription();
            ph.decodes_later = !ph.deep && !ph.tiled;
            ph.name = h.hasName() ? h.name() : std::string();
            std::vector<Chan> ch;
            for (Imf::ChannelList::ConstIterator c = h.channels().begin(); c != h.channels().end(); ++c) {
                if (c.channel().xSampling != 1 || c.channel().ySampling != 1)
                    ph.problem = "channel '" + std::string(c.name()) + "' is subsampled (" +
                                 std::to_string(c.channel().xSampling) + "x" +
                                 std::to_string(c.channel().ySampling) + "), which is not supported";
                ch.push_back(Chan{c.name(), "", "", 0, c.channel().type});
            }
            order_channels(ch);
            for (const Chan &c : ch) {
                ph.channels.push_back(c.name);
                ph.types.push_back(pix_type(c.type));
            }
            parts_.push_back(std::move(ph));
        }
    }

    const std::vector<PartHeader> &parts() const override { return parts_; }

    std::vector<Attr> attributes() const override {
        std::vector<Attr> out;
        const Imf::Header &h = file_->header(0);
        for (Imf::Header::ConstIterator i = h.begin(); i != h.end(); ++i) {
            if (layout_attr(i.name())) continue;
            StringOStream os;
            i.attribute().writeValueTo(os, 2);
            out.push_back(Attr{i.name(), i.attribute().typeName(), os.s_});
        }
        return out;
    }

    std::string compression() const override { return comp_name(file_->header(0).compression()); }

    bool read(int part, int y0, int y1, const int *chans, const BandDst *dst, size_t n, std::string &why) override {
        try {
            if (!in_[size_t(part)]) in_[size_t(part)].reset(new Imf::InputPart(*file_, part));
            Imf::InputPart &in = *in_[size_t(part)];
            const PartHeader &ph = parts_[size_t(part)];
            const Imf::Header &h = file_->header(part);
            if (zip_lines(h.compression()) && ph.decodes_later && ph.problem.empty()) {
                /* ZIP and ZIPS: inflated here (exr_zip_reader.cpp) */
                std::unique_ptr<ZipPartReader> &z = zip_[size_t(part)];
                if (!z) z.reset(new ZipPartReader(in, h));
                std::vector<std::string> names(n);
                for (size_t k = 0; k < n; k++) names[k] = ph.channels[size_t(chans[k])];
                z->read(y0, y1, names.data(), dst, n);
                return true;
            }
            Imf::FrameBuffer fb;
            /* a channel asked for twice (a pass and its alpha, say) is decoded
             * once, into its first destination, and copied to the others:
             * a frame buffer holds one slice per name */
            std::vector<std::pair<size_t, size_t>> again; /* (k, the first k of its channel) */
            for (size_t k = 0; k < n; k++) {
                size_t first = k;
                for (size_t j = 0; j < k && first == k; j++)
                    if (chans[j] == chans[k]) first = j;
                if (first != k) {
                    again.emplace_back(k, first);
                    continue;
                }
                /* OpenEXR finds pixel (x, y) at base + x * xStride + y * yStride,
                 * in the file's coordinates: the base is the band's first value
                 * moved back by the data window's origin and the band's top row
                 * (integer arithmetic: the base itself lies outside the band) */
                const size_t xs = dst[k].xs * sizeof(float), ys = dst[k].ys * sizeof(float);
                const uintptr_t base = reinterpret_cast<uintptr_t>(dst[k].p) - uintptr_t(intptr_t(ph.x) * intptr_t(xs)) -
                                       uintptr_t(intptr_t(ph.y + y0) * intptr_t(ys));
                fb.insert(ph.channels[size_t(chans[k])],
                          Imf::Slice(Imf::FLOAT, reinterpret_cast<char *>(base), xs, ys, 1, 1, 0.0));
            }
            in.setFrameBuffer(fb);
            in.readPixels(ph.y + y0, ph.y + y1 - 1);
            const size_t w = size_t(ph.width);
            for (const auto &a : again)
                for (int y = 0; y < y1 - y0; y++) {
                    const BandDst &from = dst[a.second], &to = dst[a.first];
                    for (size_t x = 0; x < w; x++)
                        to.p[size_t(y) * to.ys + x * to.xs] = from.p[size_t(y) * from.ys + x * from.xs];
                }
            return true;
        } catch (const std::bad_alloc &) {
            throw;
        } catch (const std::exception &e) {
            why = first_line(e.what(), "read failed");
            return false;
        }
    }

  private:
    std::unique_ptr<Imf::MultiPartInputFile> file_;
    std::vector<std::unique_ptr<Imf::InputPart>> in_;
    std::vector<std::unique_ptr<ZipPartReader>> zip_; /* a ZIP or ZIPS part's, made on its first read */
    std::vector<PartHeader> parts_;
};

std::unique_ptr<Reader> exr_open_reader(const std::string &path, std::string &why) {
    try {
        return std::unique_ptr<Reader>(new ExrReader(path));
    } catch (const std::bad_alloc &) {
        throw;
    } catch (const std::exception &e) {
        why = first_line(e.what(), "OpenEXR cannot read it");
        return nullptr;
    }
}

} // namespace

/* -------------------------------------------------------------- write */

namespace {
/* with the F16C instructions where the CPU has them */
__attribute__((target("avx,f16c"))) void to_half_f16c(const float *s, uint16_t *d, size_t n) {
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm_storeu_si128(reinterpret_cast<__m128i *>(d + i), _mm256_cvtps_ph(_mm256_loadu_ps(s + i), 0));
    for (; i < n; i++) d[i] = half(s[i]).bits();
}

float half_bits_to_float(uint16_t b) {
    half h;
    h.setBits(b);
    return float(h);
}

__attribute__((target("avx,f16c"))) void half_to_float_f16c(const uint16_t *s, float *d, size_t n) {
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm256_storeu_ps(d + i, _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i *>(s + i))));
    for (; i < n; i++) d[i] = half_bits_to_float(s[i]);
}

/* CPUID's F16C bit (clang's __builtin_cpu_supports does not know "f16c") */
bool has_f16c() {
    unsigned a, b, c, d;
    return __get_cpuid(1, &a, &b, &c, &d) && (c & bit_F16C) && __builtin_cpu_supports("avx");
}
} // namespace

void to_half(const float *s, uint16_t *d, size_t n) {
    static const bool f16c = has_f16c();
    if (f16c) {
        to_half_f16c(s, d, n);
        return;
    }
    for (size_t i = 0; i < n; i++) d[i] = half(s[i]).bits();
}

void half_to_float(const uint16_t *s, float *d, size_t n) {
    static const bool f16c = has_f16c();
    if (f16c) {
        half_to_float_f16c(s, d, n);
        return;
    }
    for (size_t i = 0; i < n; i++) d[i] = half_bits_to_float(s[i]);
}

void to_uint(const float *s, uint32_t *d, size_t n) {
    for (size_t i = 0; i < n; i++) {
        const float v = s[i];
        d[i] = !(v > 0.0f) ? 0u : v >= 4294967295.0f ? 4294967295u : uint32_t(v);
    }
}

namespace {

class ExrWriter final : public Writer {
  public:
    bool open(const std::string &path, const WriteSpec &s, std::string &why) override {
        try {
            ensure_pool();
            const Imath::Box2i disp(Imath::V2i(s.full_x, s.full_y),
                                    Imath::V2i(s.full_x + s.full_width - 1, s.full_y + s.full_height - 1));
            const Imath::Box2i data(Imath::V2i(s.x, s.y), Imath::V2i(s.x + s.width - 1, s.y + s.height - 1));
            Imf::Header h(disp, data);
            for (const Attr &a : s.attrs) {
                if (layout_attr(a.name)) continue;
                h.insert(a.name.c_str(), *make_attribute(a));
            }
            Imf::Compression c = Imf::ZIP_COMPRESSION;
            float level = -1.0f;
            if (!s.compression.empty() && !parse_comp(s.compression, &c, &level)) {
                why = "unknown EXR compression '" + s.compression +
                      "' (none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab)";
                return false;
            }
            h.compression() = c;
            if (level > 0.0f && (c == Imf::DWAA_COMPRESSION || c == Imf::DWAB_COMPRESSION))
                h.dwaCompressionLevel() = level;
            else if (level >= 0.0f && (c == Imf::ZIP_COMPRESSION || c == Imf::ZIPS_COMPRESSION))
                h.zipCompressionLevel() = int(level);
            for (size_t i = 0; i < s.names.size(); i++) {
                const PixType t = s.types[i];
                h.channels().insert(s.names[i], Imf::Channel(t == PixType::HALF  ? Imf::HALF
                                                             : t == PixType::U32 ? Imf::UINT
                                                                                 : Imf::FLOAT));
            }
            spec_ = s;
            if (zip_lines(c)) {
                zip_.reset(new ZipPartWriter);
                zip_->open(path, h, s);
                return true;
            }
            out_.reset(new Imf::OutputFile(path.c_str(), h, Imf::globalThreadCount()));
            return true;
        } catch (const std::bad_alloc &) {
            throw;
        } catch (const std::exception &e) {
            why = first_line(e.what(), "could not open the output");
            return false;
        }
    }

    /* OpenEXR writes each channel from a slice of its own type (it converts
     * on reading only): a float channel from the band where it is (a slice
     * has strides of its own), half and uint from planes converted here. */
    bool write(int y0, int y1, const BandSrc *src, std::string &why) override {
        try {
            if (zip_) {
                zip_->write(y0, y1, src);
                return true;
            }
            const size_t nch = spec_.names.size(), w = size_t(spec_.width), rows = size_t(y1 - y0), n = rows * w;
            size_t converted = 0;
            for (size_t c = 0; c < nch; c++) converted += spec_.types[c] != PixType::FLOAT;
            planes_.resize(converted * n * sizeof(float));
            line_.resize(w);
            Imf::FrameBuffer fb;
            char *plane = planes_.data();
            for (size_t c = 0; c < nch; c++) {
                const PixType t = spec_.types[c];
                /* the slice's origin is pixel (0, 0) of the data window */
                const auto slice = [&](Imf::PixelType pt, const void *first, size_t xs, size_t ys) {
                    const uintptr_t base = reinterpret_cast<uintptr_t>(first) -
                                           uintptr_t(intptr_t(spec_.x) * intptr_t(xs)) -
                                           uintptr_t(intptr_t(spec_.y + y0) * intptr_t(ys));
                    fb.insert(spec_.names[c], Imf::Slice(pt, reinterpret_cast<char *>(base), xs, ys));
                };
                if (t == PixType::FLOAT) {
                    slice(Imf::FLOAT, src[c].p, src[c].xs * sizeof(float), src[c].ys * sizeof(float));
                    continue;
                }
                for (size_t y = 0; y < rows; y++) {
                    const float *v = src[c].row(y, w, line_.data());
                    if (t == PixType::HALF)
                        to_half(v, reinterpret_cast<uint16_t *>(plane) + y * w, w);
                    else
                        to_uint(v, reinterpret_cast<uint32_t *>(plane) + y * w, w);
                }
                const size_t vs = t == PixType::HALF ? 2 : 4;
                slice(t == PixType::HALF ? Imf::HALF : Imf::UINT, plane, vs, w * vs);
                plane += n * sizeof(float);
            }
            out_->setFrameBuffer(fb);
            out_->writePixels(y1 - y0);
            return true;
        } catch (const std::bad_alloc &) {
            throw;
        } catch (const std::exception &e) {
            why = first_line(e.what(), "writing pixels failed");
            return false;
        }
    }

    /* OpenEXR writes the chunk table in its destructor, which swallows a
     * failure: ewio checks the written file's chunks afterwards. */
    bool close(std::string &why) override {
        try {
            if (zip_) zip_->close();
            zip_.reset();
            out_.reset();
            return true;
        } catch (const std::exception &e) {
            why = first_line(e.what(), "closing the output failed");
            return false;
        }
    }

  private:
    WriteSpec spec_;
    std::unique_ptr<Imf::OutputFile> out_;
    std::unique_ptr<ZipPartWriter> zip_; /* ZIP and ZIPS: deflated here (exr_zip_writer.cpp) */
    std::vector<char> planes_; /* half and uint channels of a band, converted */
    std::vector<float> line_;  /* a channel's row gathered */
};

std::unique_ptr<Writer> exr_create_writer() {
    return std::unique_ptr<Writer>(new ExrWriter);
}

/* Every chunk decoded, in bands into a throwaway buffer. */
bool exr_read_back(const std::string &path, long long w, long long h, long long nch, std::string &why) {
    std::unique_ptr<Reader> r = exr_open_reader(path, why);
    if (!r) return false;
    const std::vector<PartHeader> &ps = r->parts();
    long long n = 0;
    for (const PartHeader &p : ps) n += (long long)p.channels.size();
    if (ps.size() != 1 || ps[0].width != w || ps[0].height != h || n != nch) {
        why = reads_as(ps.empty() ? 0 : ps[0].width, ps.empty() ? 0 : ps[0].height, n);
        return false;
    }
    const size_t rows = band_rows_of(size_t(w) * size_t(nch) * sizeof(float), size_t(h));
    std::vector<float> buf(rows * size_t(w) * size_t(nch));
    std::vector<int> chans(static_cast<size_t>(nch));
    std::vector<BandDst> dst(static_cast<size_t>(nch));
    for (size_t c = 0; c < size_t(nch); c++) {
        chans[c] = int(c);
        dst[c] = BandDst{buf.data() + c, size_t(nch), size_t(w) * size_t(nch)};
    }
    for (long long y0 = 0; y0 < h; y0 += (long long)rows)
        if (!r->read(0, int(y0), int(std::min<long long>(h, y0 + (long long)rows)), chans.data(), dst.data(),
                     dst.size(), why))
            return false;
    return true;
}

/* --------------------------------------------------------- attr text */

template <class T> T get_le(const std::string &v, size_t at) {
    unsigned char b[sizeof(T)];
    for (size_t i = 0; i < sizeof(T); i++) b[i] = (unsigned char)v[at + i];
    T x;
    std::memcpy(&x, b, sizeof(T)); /* the machine is little-endian, as the file */
    return x;
}

template <class T> std::string num(T x) {
    char b[64];
    const auto r = std::to_chars(b, b + sizeof b, x);
    return std::string(b, r.ptr);
}

template <class T> std::string nums(const std::string &v, size_t count) {
    if (v.size() < count * sizeof(T)) return std::string();
    std::string o;
    for (size_t i = 0; i < count; i++) o += (i ? ", " : "") + num(get_le<T>(v, i * sizeof(T)));
    return o;
}

} // namespace

std::string attr_text(const Attr &a) {
    const std::string &t = a.type, &v = a.value;
    if (t == "string") return v;
    if (t == "int") return nums<int32_t>(v, 1);
    if (t == "float") return nums<float>(v, 1);
    if (t == "double") return nums<double>(v, 1);
    if (t == "v2i") return nums<int32_t>(v, 2);
    if (t == "v2f") return nums<float>(v, 2);
    if (t == "v2d") return nums<double>(v, 2);
    if (t == "v3i") return nums<int32_t>(v, 3);
    if (t == "v3f") return nums<float>(v, 3);
    if (t == "v3d") return nums<double>(v, 3);
    if (t == "box2i") return nums<int32_t>(v, 4);
    if (t == "box2f") return nums<float>(v, 4);
    if (t == "m33f") return nums<float>(v, 9);
    if (t == "m33d") return nums<double>(v, 9);
    if (t == "m44f") return nums<float>(v, 16);
    if (t == "m44d") return nums<double>(v, 16);
    if (t == "chromaticities") return nums<float>(v, 8);
    if (t == "floatvector") return nums<float>(v, v.size() / 4);
    if (t == "rational" && v.size() >= 8) return num(get_le<int32_t>(v, 0)) + "/" + num(get_le<uint32_t>(v, 4));
    if (t == "stringvector") {
        std::string o;
        for (size_t at = 0; at + 4 <= v.size();) {
            const size_t n = get_le<uint32_t>(v, at);
            if (n > v.size() - at - 4) break;
            o += (o.empty() ? "" : ", ") + v.substr(at + 4, n);
            at += 4 + n;
        }
        return o;
    }
    return std::string();
}

const Codec &exr_codec() {
    static const Codec c = {exr_open_reader, exr_create_writer, exr_read_back, exr_set_threads};
    return c;
}

} // namespace ewio
