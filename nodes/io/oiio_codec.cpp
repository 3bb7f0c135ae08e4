/*
 * oiio_codec.cpp — PNG, TIFF, JPEG and the other formats OpenImageIO reads
 * (codec.h), built as the module libedgewise_oiio.so that ewio loads the
 * first time such a file is read or written (oiio_module.cpp).
 *
 * Values as OpenImageIO converts them: integer samples read as 0..1, colour
 * associated with alpha on read and un-associated on PNG/TIFF output.
 */
#include "codec.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

namespace ewio {
namespace {

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::ParamValue;
using OIIO::TypeDesc;

std::string oiio_msg(const std::string &m, const char *fallback) { return first_line(m, fallback); }

PixType pix_type(TypeDesc t) {
    switch (t.basetype) {
    case TypeDesc::UINT8: return PixType::U8;
    case TypeDesc::INT8: return PixType::I8;
    case TypeDesc::UINT16: return PixType::U16;
    case TypeDesc::INT16: return PixType::I16;
    case TypeDesc::UINT32: return PixType::U32;
    case TypeDesc::INT32: return PixType::I32;
    case TypeDesc::HALF: return PixType::HALF;
    case TypeDesc::DOUBLE: return PixType::DOUBLE;
    default: return PixType::FLOAT;
    }
}

TypeDesc type_desc(PixType t) {
    switch (t) {
    case PixType::U8: return OIIO::TypeUInt8;
    case PixType::U16: return OIIO::TypeUInt16;
    case PixType::HALF: return OIIO::TypeHalf;
    default: return OIIO::TypeFloat;
    }
}

/* Where OpenImageIO and OpenEXR name the same metadata differently, the
 * model keeps OpenEXR's name. */
const char *const kRenames[][2] = {{"ImageDescription", "comments"}, {"Copyright", "owner"}, {"DateTime", "capDate"}};

std::string to_model_name(const std::string &n) {
    for (const auto &r : kRenames)
        if (n == r[0]) return r[1];
    return n;
}

std::string to_oiio_name(const std::string &n) {
    for (const auto &r : kRenames)
        if (n == r[1]) return r[0];
    return n;
}

class OiioReader final : public Reader {
  public:
    bool open(const std::string &path, std::string &why) {
        in_ = ImageInput::open(path);
        if (!in_) {
            why = oiio_msg(OIIO::geterror(), "no reader accepted it");
            return false;
        }
        for (int sub = 0;; sub++) {
            if (sub > 0 && !in_->seek_subimage(sub, 0)) break;
            const ImageSpec &s = in_->spec();
            PartHeader ph;
            ph.width = s.width;
            ph.height = s.height;
            ph.x = s.x;
            ph.y = s.y;
            ph.full_x = s.full_x;
            ph.full_y = s.full_y;
            ph.full_width = s.full_width > 0 ? s.full_width : s.width;
            ph.full_height = s.full_height > 0 ? s.full_height : s.height;
            ph.deep = s.deep;
            ph.volume = s.depth > 1;
            ph.tiled = s.tile_width > 0;
            ph.name = s.get_string_attribute("oiio:subimagename");
            for (int c = 0; c < s.nchannels; c++) {
                ph.channels.push_back(c < int(s.channelnames.size()) ? s.channelnames[size_t(c)] : std::string());
                ph.types.push_back(pix_type(s.channelformat(c)));
            }
            parts_.push_back(std::move(ph));
            if (sub == 0) {
                for (const ParamValue &p : s.extra_attribs) {
                    const std::string n = p.name().string();
                    if (n.compare(0, 5, "oiio:") == 0) continue;
                    if (p.type() == OIIO::TypeString)
                        attrs_.push_back(attr_string(to_model_name(n), p.get_string()));
                    else if (p.type() == OIIO::TypeInt)
                        attrs_.push_back(attr_int(to_model_name(n), p.get_int()));
                    else if (p.type() == OIIO::TypeFloat)
                        attrs_.push_back(attr_float(to_model_name(n), p.get_float()));
                }
            }
        }
        (void)in_->geterror(); /* the "no such subimage" noise of the scan's end */
        return true;
    }

    const std::vector<PartHeader> &parts() const override { return parts_; }
    std::vector<Attr> attributes() const override { return attrs_; }

    bool read(int part, int y0, int y1, const int *chans, const BandDst *dst, size_t n, std::string &why) override {
        const PartHeader &ph = parts_[size_t(part)];
        const size_t w = size_t(ph.width), nch = ph.channels.size();
        bool ok;
        buf_.resize(size_t(y1 - y0) * w * nch);
        /* the reads name their subimage: OpenImageIO seeks to it itself */
        if (ph.tiled) /* OpenImageIO assembles the tiles: the whole image in one band */
            ok = y0 == 0 && y1 == int(ph.height) && in_->read_image(part, 0, 0, int(nch), OIIO::TypeFloat, buf_.data());
        else
            ok = in_->read_scanlines(part, 0, ph.y + y0, ph.y + y1, 0, 0, int(nch), OIIO::TypeFloat, buf_.data());
        if (!ok || in_->has_error()) { /* e.g. libjpeg's "premature end" is only a warning */
            why = oiio_msg(in_->geterror(), "read failed");
            return false;
        }
        for (size_t k = 0; k < n; k++) {
            const float *s = buf_.data() + chans[k];
            for (int y = 0; y < y1 - y0; y++) {
                float *o = dst[k].p + size_t(y) * dst[k].ys;
                const float *r = s + size_t(y) * w * nch;
                for (size_t x = 0; x < w; x++) o[x * dst[k].xs] = r[x * nch];
            }
        }
        return true;
    }

  private:
    std::unique_ptr<ImageInput> in_;
    std::vector<PartHeader> parts_;
    std::vector<Attr> attrs_;
    std::vector<float> buf_;
};

std::unique_ptr<Reader> oiio_open_reader(const std::string &path, std::string &why) {
    std::unique_ptr<OiioReader> r(new OiioReader);
    if (!r->open(path, why)) return nullptr;
    return r;
}

class OiioWriter final : public Writer {
  public:
    bool open(const std::string &path, const WriteSpec &s, std::string &why) override {
        TypeDesc widest = type_desc(s.types[0]);
        bool mixed = false;
        std::vector<TypeDesc> fmts;
        for (PixType t : s.types) {
            fmts.push_back(type_desc(t));
            mixed = mixed || fmts.back() != fmts[0];
            if (fmts.back().size() > widest.size()) widest = fmts.back();
        }
        spec_ = ImageSpec(s.width, s.height, int(s.names.size()), widest);
        spec_.channelnames = s.names;
        if (mixed) spec_.channelformats = fmts;
        spec_.alpha_channel = -1;
        spec_.z_channel = -1;
        for (size_t c = 0; c < s.names.size(); c++)
            if (s.names[c] == "A") spec_.alpha_channel = int(c);
        /* Plain text metadata only (Cycles' samples, camera, scene...). */
        for (const Attr &a : s.attrs) {
            if (a.type != "string" || a.name == "compression" || a.name.find(':') != std::string::npos) continue;
            spec_.attribute(to_oiio_name(a.name), a.value);
        }
        out_ = ImageOutput::create(path); /* the format from the destination's extension */
        if (!out_) {
            why = "no writer for this extension (" + oiio_msg(OIIO::geterror(), "OpenImageIO has no such format") + ")";
            return false;
        }
        path_ = path;
        /* JPEG is encoded into memory and written out here: on a write error
         * (disk full, file size limit) OpenImageIO 2.4's JPEG writer leaves
         * libjpeg's default handler in place, which prints and calls exit(). */
        const std::string fmt = out_->format_name();
        if (fmt == "jpeg") {
            mem_.reset(new OIIO::Filesystem::IOVecOutput());
            if (!out_->supports("ioproxy") || !out_->set_ioproxy(mem_.get())) {
                why = "this OpenImageIO cannot encode JPEG to memory (no I/O proxy support)";
                return false;
            }
        }
        if (!out_->open(path, spec_)) {
            why = oiio_msg(out_->geterror(), "could not open the output");
            return false;
        }
        return true;
    }

    /* OpenImageIO takes a band's channels interleaved */
    bool write(int y0, int y1, const BandSrc *src, std::string &why) override {
        const size_t nch = size_t(spec_.nchannels), w = size_t(spec_.width), rows = size_t(y1 - y0);
        band_.resize(rows * w * nch);
        for (size_t c = 0; c < nch; c++)
            for (size_t y = 0; y < rows; y++)
                for (size_t x = 0; x < w; x++) band_[(y * w + x) * nch + c] = src[c].at(y, x);
        if (!out_->write_scanlines(spec_.y + y0, spec_.y + y1, 0, OIIO::TypeFloat, band_.data()) || out_->has_error()) {
            why = oiio_msg(out_->geterror(), "writing pixels failed");
            return false;
        }
        return true;
    }

    /* close()'s own result decides here, not has_error(): OpenImageIO 2.4's
     * TIFF writer logs "failed TIFFWriteCustomDirectory() of the Exif data"
     * on every close although the file is fine. ewio's read-back vouches
     * for the file. */
    bool close(std::string &why) override {
        if (!out_->close()) {
            why = oiio_msg(out_->geterror(), "closing the output failed");
            return false;
        }
        out_.reset();
        if (!mem_) return true;
        const std::vector<unsigned char> &bytes = mem_->buffer();
        int fd = ::open(path_.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
        size_t done = 0;
        int e = fd < 0 ? errno : 0;
        while (fd >= 0 && done < bytes.size()) {
            ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) {
                e = n < 0 ? errno : EIO;
                break;
            }
            done += size_t(n);
        }
        if (fd >= 0 && ::close(fd) != 0 && e == 0) e = errno;
        if (e != 0 || done != bytes.size()) {
            why = std::string("writing the temporary file failed (") + std::strerror(e ? e : EIO) + ")";
            return false;
        }
        return true;
    }

    ~OiioWriter() override {
        out_.reset(); /* before mem_, which it may still write into */
    }

  private:
    ImageSpec spec_;
    std::vector<float> band_; /* a band interleaved */
    std::string path_;
    std::unique_ptr<OIIO::Filesystem::IOVecOutput> mem_;
    std::unique_ptr<ImageOutput> out_;
};

std::unique_ptr<Writer> oiio_create_writer() {
    return std::unique_ptr<Writer>(new OiioWriter);
}

bool oiio_read_back(const std::string &path, long long w, long long h, long long nch, std::string &why) {
    auto in = ImageInput::open(path);
    if (!in) {
        why = oiio_msg(OIIO::geterror(), "cannot open it");
        return false;
    }
    const ImageSpec s = in->spec();
    if (s.width != w || s.height != h || s.nchannels != nch) {
        why = reads_as(s.width, s.height, s.nchannels);
        return false;
    }
    bool ok;
    if (s.tile_width > 0) {
        std::vector<float> buf(size_t(w) * size_t(h) * size_t(nch));
        ok = in->read_image(0, 0, 0, int(nch), OIIO::TypeFloat, buf.data());
    } else {
        /* decoding is the check: the stored types, no conversion */
        const size_t pxb = s.pixel_bytes(true);
        const size_t rows = band_rows_of(size_t(w) * pxb, size_t(h));
        std::vector<unsigned char> buf(rows * size_t(w) * pxb);
        ok = true;
        for (long long y0 = 0; ok && y0 < h; y0 += (long long)rows) {
            const long long y1 = std::min(h, y0 + (long long)rows);
            ok = in->read_native_scanlines(0, 0, s.y + int(y0), s.y + int(y1), 0, 0, int(nch), buf.data());
        }
    }
    if (!ok) why = oiio_msg(in->geterror(), "cannot read its pixels");
    return ok;
}

void oiio_set_threads(int n) {
    OIIO::attribute("threads", n);
    OIIO::attribute("exr_threads", n);
}

} // namespace
} // namespace ewio

/* Every entry point catches what it must: ewio.cpp calls them inside its
 * own try blocks, as it calls the OpenEXR codec's. */
extern "C" __attribute__((visibility("default"))) const ewio::Codec *ewio_oiio_codec(void) {
    static const ewio::Codec c = {ewio::oiio_open_reader, ewio::oiio_create_writer, ewio::oiio_read_back,
                                  ewio::oiio_set_threads};
    return &c;
}
