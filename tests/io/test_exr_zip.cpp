/*
 * test_exr_zip.cpp — the ZIP/ZIPS part writer (nodes/io/exr_zip_writer.cpp)
 * read back by OpenEXR's own reader: every value exact after the file's
 * conversion, whatever bands the rows come in (chunks of 16 rows that
 * straddle bands), with the channels in another order than the file's,
 * a data window off the origin, a name of 32 bytes or more, chunks that do
 * not compress stored as they are; and the ZIP/ZIPS part reader
 * (exr_zip_reader.cpp) on files OpenEXR wrote, against OpenEXR's reading.
 */
#include "ew_test.h"

#include "exr_zip.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <Imath/half.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

const char *const kLong = "ViewLayer.A pass whose name is long.R"; /* 37 bytes */

struct Case {
    Imf::Compression comp;
    int w, h, x0, y0;
    std::vector<int> bands; /* rows a write() call, repeated to the end */
    bool noise;             /* values of random bits: chunks that do not compress */
};

std::string temp_path() {
    char p[] = "/tmp/ew_zip_XXXXXX.exr";
    const int fd = mkstemps(p, 4);
    if (fd >= 0) close(fd);
    return p;
}

/* The band's channels, in the order given to the writer (not the file's). */
ewio::WriteSpec spec_of(const Case &c) {
    ewio::WriteSpec s;
    s.width = s.full_width = c.w;
    s.height = s.full_height = c.h;
    s.x = s.full_x = c.x0;
    s.y = s.full_y = c.y0;
    s.names = {"Z", kLong, "B", "A"};
    s.types = {ewio::PixType::U32, ewio::PixType::FLOAT, ewio::PixType::FLOAT, ewio::PixType::HALF};
    if (c.noise) s.types.assign(4, ewio::PixType::FLOAT); /* random bits as they are: nothing to deflate */
    return s;
}

std::vector<float> values_of(const Case &c) {
    const size_t n = size_t(c.w) * size_t(c.h) * 4;
    std::vector<float> v(n);
    std::mt19937 rng(7);
    for (size_t i = 0; i < n; i++) {
        if (c.noise) {
            const uint32_t bits = uint32_t(rng());
            std::memcpy(&v[i], &bits, 4);
        } else {
            const size_t px = i / 4, x = px % size_t(c.w), y = px / size_t(c.w);
            v[i] = 0.01f * float(x) + 0.5f * float(y) + (i % 4 == 0 ? 3.0f : -0.25f * float(i % 4));
        }
    }
    return v;
}

/* The 4 channels of row y of v (interleaved, w wide) as a band's sources,
 * interleaved as they are or (planes, c x w x h floats) from planes. */
std::vector<ewio::BandSrc> band_at(const std::vector<float> &v, const std::vector<float> *planes, size_t w, size_t h,
                                   int y) {
    std::vector<ewio::BandSrc> b(4);
    for (size_t c = 0; c < 4; c++)
        b[c] = planes ? ewio::BandSrc{planes->data() + c * w * h + size_t(y) * w, 1, w}
                      : ewio::BandSrc{v.data() + size_t(y) * w * 4 + c, 4, w * 4};
    return b;
}

/* Write case c, read it back with Imf::InputFile and compare; 1 when equal. */
int roundtrip(const Case &c, std::string *why) {
    const std::string path = temp_path();
    const ewio::WriteSpec s = spec_of(c);
    const std::vector<float> v = values_of(c);
    Imf::Header h(Imath::Box2i(Imath::V2i(c.x0, c.y0), Imath::V2i(c.x0 + c.w - 1, c.y0 + c.h - 1)),
                  Imath::Box2i(Imath::V2i(c.x0, c.y0), Imath::V2i(c.x0 + c.w - 1, c.y0 + c.h - 1)));
    h.compression() = c.comp;
    h.insert("owner", Imf::StringAttribute("edgewise test"));
    for (size_t i = 0; i < s.names.size(); i++)
        h.channels().insert(s.names[i], Imf::Channel(s.types[i] == ewio::PixType::HALF  ? Imf::HALF
                                                     : s.types[i] == ewio::PixType::U32 ? Imf::UINT
                                                                                        : Imf::FLOAT));
    std::vector<float> planes(v.size());
    for (size_t i = 0; i < v.size(); i++) planes[i % 4 * (v.size() / 4) + i / 4] = v[i];
    {
        ewio::ZipPartWriter w;
        w.open(path, h, s);
        /* bands from interleaved values and from planes in turn */
        for (int y = 0, k = 0; y < c.h; k++) {
            const int y1 = std::min(c.h, y + c.bands[size_t(k) % c.bands.size()]);
            w.write(y, y1, band_at(v, k % 2 ? &planes : nullptr, size_t(c.w), size_t(c.h), y).data());
            y = y1;
        }
        w.close();
    }
    Imf::InputFile in(path.c_str());
    const size_t n = size_t(c.w) * size_t(c.h), origin = size_t(c.x0) + size_t(c.y0) * size_t(c.w);
    /* every channel read in its own type into 4-byte slots (a half in the low two bytes) */
    std::vector<std::vector<uint32_t>> got(s.names.size(), std::vector<uint32_t>(n));
    Imf::FrameBuffer fb;
    for (size_t k = 0; k < s.names.size(); k++) {
        const Imf::PixelType t = s.types[k] == ewio::PixType::HALF  ? Imf::HALF
                                 : s.types[k] == ewio::PixType::U32 ? Imf::UINT
                                                                    : Imf::FLOAT;
        fb.insert(s.names[k], Imf::Slice(t, reinterpret_cast<char *>(got[k].data() - origin), 4, 4 * size_t(c.w)));
    }
    in.setFrameBuffer(fb);
    in.readPixels(c.y0, c.y0 + c.h - 1);
    const Imf::StringAttribute *owner = in.header().findTypedAttribute<Imf::StringAttribute>("owner");
    if (!owner || owner->value() != "edgewise test") return *why = "the header's attribute did not come back", 0;
    for (size_t i = 0; i < n; i++)
        for (size_t k = 0; k < s.names.size(); k++) {
            const float f = v[i * 4 + k];
            uint32_t want;
            if (s.types[k] == ewio::PixType::U32) {
                ewio::to_uint(&f, &want, 1);
            } else if (s.types[k] == ewio::PixType::HALF) {
                want = half(f).bits();
            } else {
                std::memcpy(&want, &f, 4);
            }
            if (got[k][i] != want) {
                *why = "pixel " + std::to_string(i) + " of " + s.names[k] + " differs";
                return 0;
            }
        }
    /* chunks that do not compress are stored as they are: their size is the rows' own */
    int stored = 0;
    const int lines = c.comp == Imf::ZIPS_COMPRESSION ? 1 : 16;
    for (int y = 0; y < c.h; y += lines) {
        const char *data;
        int size;
        in.rawPixelData(c.y0 + y, data, size);
        stored += size == std::min(lines, c.h - y) * c.w * (c.noise ? 16 : 4 + 4 + 4 + 2);
    }
    unlink(path.c_str());
    if (c.noise && stored == 0) return *why = "no chunk of random bits was stored as it is", 0;
    if (!c.noise && c.w >= 16 && stored > 0) return *why = "a chunk of smooth values was stored uncompressed", 0;
    return 1;
}

} // namespace

/* The byte transforms (exr_zip_bytes.cpp, in blocks of 16 and 32 bytes)
 * give the bytes of the format's own byte loops, at every length around
 * the blocks' sizes (the tails) and on random bytes (every carry). */
TEST(byte_transforms_are_the_formats_byte_loops) {
    std::mt19937 rng(7);
    for (size_t n : {0, 1, 2, 3, 15, 16, 17, 18, 31, 32, 33, 34, 47, 48, 63, 64, 65, 100, 255, 4097}) {
        std::vector<unsigned char> raw(n);
        for (unsigned char &b : raw) b = (unsigned char)rng();
        /* encoding as the specification writes it */
        std::vector<unsigned char> want(n);
        for (size_t i = 0; i < n; i++) want[i % 2 ? (n + 1) / 2 + i / 2 : i / 2] = raw[i];
        for (size_t i = n; i-- > 1;) want[i] = (unsigned char)(want[i] - want[i - 1] + 128);
        std::vector<unsigned char> t(n + 1, 0xee);
        ewio::zip_split(raw.data(), n, t.data());
        ewio::zip_predict(t.data(), n);
        CHECK(std::equal(want.begin(), want.end(), t.begin()));
        CHECK(t[n] == 0xee);
        /* and back: the sums, then any even stretch merged */
        ewio::zip_unpredict(t.data(), n);
        for (size_t i = 1; i < n; i++) want[i] = (unsigned char)(want[i - 1] + want[i] - 128);
        CHECK(std::equal(want.begin(), want.end(), t.begin()));
        for (size_t at = 0; at + 2 <= n; at += n / 4 * 2 + 2) {
            const size_t len = (n - at) / 2 * 2;
            std::vector<unsigned char> back(len + 1, 0xee);
            ewio::zip_merge(t.data() + at / 2, t.data() + (n + 1) / 2 + at / 2, len / 2, back.data());
            CHECK(std::equal(back.begin(), back.begin() + long(len), raw.begin() + long(at)));
            CHECK(back[len] == 0xee);
        }
    }
}

TEST(zip_and_zips_read_back_exactly_in_any_bands) {
    const std::vector<std::vector<int>> bands = {{1000}, {1}, {7}, {20, 3}, {16}, {33}};
    for (Imf::Compression comp : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION})
        for (const std::vector<int> &b : bands) {
            std::string why;
            const Case c{comp, 37, 45, -3, 5, b, false};
            const int ok = roundtrip(c, &why);
            if (!ok) fprintf(stderr, "  compression %d, bands of %d: %s\n", int(comp), b[0], why.c_str());
            CHECK(ok);
        }
}

TEST(one_row_and_one_column) {
    std::string why;
    const int one = roundtrip(Case{Imf::ZIP_COMPRESSION, 1, 1, 0, 0, {1}, false}, &why);
    if (!one) fprintf(stderr, "  %s\n", why.c_str());
    CHECK(one);
    CHECK(roundtrip(Case{Imf::ZIP_COMPRESSION, 1, 17, 0, 0, {5}, false}, &why));
    CHECK(roundtrip(Case{Imf::ZIPS_COMPRESSION, 300, 1, 10, -10, {1}, false}, &why));
}

TEST(incompressible_chunks_stored_as_they_are) {
    std::string why;
    const int ok = roundtrip(Case{Imf::ZIP_COMPRESSION, 64, 40, 0, 0, {24}, true}, &why);
    if (!ok) fprintf(stderr, "  %s\n", why.c_str());
    CHECK(ok);
}

TEST(rows_out_of_order_and_missing_rows_fail) {
    const std::string path = temp_path();
    Case c{Imf::ZIP_COMPRESSION, 8, 20, 0, 0, {4}, false};
    const ewio::WriteSpec s = spec_of(c);
    Imf::Header h(8, 20);
    h.compression() = Imf::ZIP_COMPRESSION;
    for (size_t i = 0; i < s.names.size(); i++) h.channels().insert(s.names[i], Imf::Channel(Imf::FLOAT));
    const std::vector<float> v = values_of(c);
    int threw = 0;
    {
        ewio::ZipPartWriter w;
        w.open(path, h, s);
        w.write(0, 4, band_at(v, nullptr, 8, 20, 0).data());
        try {
            w.write(8, 12, band_at(v, nullptr, 8, 20, 8).data());
        } catch (const std::runtime_error &) {
            threw++;
        }
        try {
            w.close(); /* 4 of 20 rows */
        } catch (const std::runtime_error &) {
            threw++;
        }
    }
    unlink(path.c_str());
    CHECK_EQ_INT(threw, 2);
}

/* A file OpenEXR writes (ZIP or ZIPS, rows in either order), read by the
 * part reader in bands, into interleaved destinations, with a channel
 * asked twice: the floats OpenEXR's own reading gives, bit for bit. */
static int reader_matches(Imf::Compression comp, Imf::LineOrder order, int band, std::string *why) {
    const int w = 29, h = 37, x0 = 4, y0 = -6;
    const std::string path = temp_path();
    const Imath::Box2i win(Imath::V2i(x0, y0), Imath::V2i(x0 + w - 1, y0 + h - 1));
    const char *const names[3] = {"h", "f", "u"};
    const Imf::PixelType types[3] = {Imf::HALF, Imf::FLOAT, Imf::UINT};
    const size_t n = size_t(w) * size_t(h), origin = size_t(x0) + size_t(y0) * size_t(w);
    std::vector<std::vector<uint32_t>> vals(3, std::vector<uint32_t>(n));
    std::mt19937 rng(3);
    for (size_t i = 0; i < n; i++) {
        vals[0][i] = half(0.1f * float(i % 97) - 2.0f).bits();
        const float f = float(i % 13) * 0.37f + float(rng() % 5);
        std::memcpy(&vals[1][i], &f, 4);
        vals[2][i] = uint32_t(rng() % 70000);
    }
    {
        Imf::Header hd(win, win);
        hd.compression() = comp;
        hd.lineOrder() = order;
        Imf::FrameBuffer fb;
        for (int c = 0; c < 3; c++) {
            hd.channels().insert(names[c], Imf::Channel(types[c]));
            fb.insert(names[c], Imf::Slice(types[c], reinterpret_cast<char *>(vals[size_t(c)].data() - origin), 4,
                                           4 * size_t(w)));
        }
        Imf::OutputFile out(path.c_str(), hd);
        out.setFrameBuffer(fb);
        out.writePixels(h);
    }
    /* OpenEXR's reading, as float */
    std::vector<float> ref(n * 3);
    {
        Imf::InputFile in(path.c_str());
        Imf::FrameBuffer fb;
        for (int c = 0; c < 3; c++)
            fb.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char *>(ref.data() + c - origin * 3), 12,
                                           12 * size_t(w)));
        in.setFrameBuffer(fb);
        in.readPixels(y0, y0 + h - 1);
    }
    Imf::MultiPartInputFile file(path.c_str());
    Imf::InputPart part(file, 0);
    ewio::ZipPartReader r(part, file.header(0));
    /* four destinations a pixel: u, h, f, and u again */
    std::vector<float> got(n * 4, -1.0f);
    const std::string asked[4] = {"u", "h", "f", "u"};
    for (int y = 0; y < h; y += band) {
        const int y1 = std::min(h, y + band);
        ewio::BandDst dst[4];
        for (int k = 0; k < 4; k++) dst[k] = ewio::BandDst{got.data() + size_t(y) * size_t(w) * 4 + size_t(k), 4, 4 * size_t(w)};
        r.read(y, y1, asked, dst, 4);
    }
    unlink(path.c_str());
    const int refc[4] = {2, 0, 1, 2};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 4; k++)
            if (std::memcmp(&got[i * 4 + size_t(k)], &ref[i * 3 + size_t(refc[k])], 4) != 0) {
                *why = "pixel " + std::to_string(i) + " of " + asked[k] + " differs";
                return 0;
            }
    return 1;
}

TEST(reader_gives_openexrs_floats) {
    for (Imf::Compression comp : {Imf::ZIP_COMPRESSION, Imf::ZIPS_COMPRESSION})
        for (Imf::LineOrder order : {Imf::INCREASING_Y, Imf::DECREASING_Y})
            for (int band : {1, 5, 16, 40}) {
                std::string why;
                const int ok = reader_matches(comp, order, band, &why);
                if (!ok) fprintf(stderr, "  compression %d, order %d, bands of %d: %s\n", int(comp), int(order), band,
                                 why.c_str());
                CHECK(ok);
            }
}

/* A chunk whose deflated bytes are damaged is an error, not a crash nor
 * wrong floats. */
TEST(reader_refuses_a_damaged_chunk) {
    const std::string path = temp_path();
    const int w = 64, h = 32;
    {
        Imf::Header hd(w, h);
        hd.compression() = Imf::ZIP_COMPRESSION;
        hd.channels().insert("f", Imf::Channel(Imf::FLOAT));
        std::vector<float> v(size_t(w) * h);
        for (size_t i = 0; i < v.size(); i++) v[i] = float(i % 50);
        Imf::FrameBuffer fb;
        fb.insert("f", Imf::Slice(Imf::FLOAT, reinterpret_cast<char *>(v.data()), 4, 4 * size_t(w)));
        Imf::OutputFile out(path.c_str(), hd);
        out.setFrameBuffer(fb);
        out.writePixels(h);
    }
    /* the second chunk's data: after its y and size, clobbered */
    uint64_t at = 0;
    {
        Imf::InputFile in(path.c_str());
        const char *data;
        int size;
        in.rawPixelData(16, data, size);
        CHECK(size > 16 && size < w * 16 * 4);
    }
    FILE *f = fopen(path.c_str(), "r+b");
    CHECK(f != nullptr);
    /* the chunk table follows the header: find it as OpenEXR does not say */
    std::vector<unsigned char> bytes;
    int c;
    while ((c = fgetc(f)) != EOF) bytes.push_back((unsigned char)c);
    for (size_t i = 0; i + 8 <= bytes.size(); i++) {
        int32_t y;
        std::memcpy(&y, &bytes[i], 4);
        int32_t sz;
        std::memcpy(&sz, &bytes[i + 4], 4);
        if (y == 16 && sz > 16 && size_t(sz) + i + 8 <= bytes.size() && i + 8 + size_t(sz) == bytes.size()) at = i + 8;
    }
    CHECK(at > 0);
    for (size_t i = at + 2; i < at + 12; i++) bytes[i] ^= 0x5a;
    fseek(f, 0, SEEK_SET);
    CHECK(fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size());
    fclose(f);
    Imf::MultiPartInputFile file(path.c_str());
    Imf::InputPart part(file, 0);
    ewio::ZipPartReader r(part, file.header(0));
    std::vector<float> got(size_t(w) * h);
    const std::string asked[1] = {"f"};
    const ewio::BandDst dst[1] = {ewio::BandDst{got.data(), 1, size_t(w)}};
    std::string what;
    try {
        r.read(0, h, asked, dst, 1);
    } catch (const std::exception &e) {
        what = e.what();
    }
    unlink(path.c_str());
    CHECK_STR_CONTAINS(what.c_str(), "damaged");
}
