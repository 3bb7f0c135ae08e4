/*
 * test_exr_zip.cpp — the ZIP/ZIPS part writer (nodes/io/exr_zip_writer.cpp)
 * read back by OpenEXR's own reader: every value exact after the file's
 * conversion, whatever bands the rows come in (chunks of 16 rows that
 * straddle bands), with the channels in another order than the file's,
 * a data window off the origin, a name of 32 bytes or more, chunks that do
 * not compress stored as they are.
 */
#include "ew_test.h"

#include "exr_write.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
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
    {
        ewio::ZipPartWriter w;
        w.open(path, h, s);
        for (int y = 0, k = 0; y < c.h; k++) {
            const int y1 = std::min(c.h, y + c.bands[size_t(k) % c.bands.size()]);
            w.write(y, y1, v.data() + size_t(y) * size_t(c.w) * 4);
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
        w.write(0, 4, v.data());
        try {
            w.write(8, 12, v.data());
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
