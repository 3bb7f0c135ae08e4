/*
 * exr_zip.h — what the EXR codec does itself, for parts of ZIP or ZIPS
 * compression (internal to nodes/io): their chunks inflated and deflated
 * with libdeflate, where Debian 12's OpenEXR (3.1) goes through zlib at a
 * third of the speed (exr_zip_writer.cpp gives the figures). OpenEXR still
 * reads and writes the headers and chunk tables, and every other
 * compression (exr_codec.cpp). Also what both paths share with the
 * codec: the conversions between floats and the file's pixel types, and
 * jobs on OpenEXR's thread pool.
 */
#pragma once

#include "codec.h"

#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>

#include <cstdint>
#include <functional>
#include <memory>

namespace ewio {

/* ZIP's rows a chunk (ZIPS: 1), or 0 for another compression */
inline int zip_lines(Imf::Compression c) {
    return c == Imf::ZIP_COMPRESSION ? 16 : c == Imf::ZIPS_COMPRESSION ? 1 : 0;
}

/* float -> half, rounding to nearest even (as Imath's half(float)) */
void to_half(const float *s, uint16_t *d, size_t n);
/* float -> uint as OpenEXR converts it: negative and NaN to 0, clamped above */
void to_uint(const float *s, uint32_t *d, size_t n);
/* half -> float (exact) */
void half_to_float(const uint16_t *s, float *d, size_t n);

/* ZIP's byte transforms around deflate (exr_zip_bytes.cpp). Encoding: the
 * n bytes of a chunk's rows split into t, the even-indexed bytes then the
 * odd-indexed ones (zip_split), then each byte but the first replaced by
 * its difference from the one before plus 128, in place (zip_predict).
 * Decoding undoes them: zip_unpredict in place, and zip_merge, which
 * interleaves `pairs` bytes of each half back into 2 x pairs bytes of the
 * rows (any even stretch of them: the halves' bytes from that place on). */
void zip_split(const unsigned char *raw, size_t n, unsigned char *t);
void zip_predict(unsigned char *t, size_t n);
void zip_unpredict(unsigned char *t, size_t n);
void zip_merge(const unsigned char *even, const unsigned char *odd, size_t pairs, unsigned char *raw);

/* job(0) .. job(k - 1) on OpenEXR's pool threads (each in the caller's
 * thread when the pool has none), waiting for them all; what a job threw
 * (the first by index) is thrown again in the caller's thread. */
void run_on_pool(size_t k, const std::function<void(size_t)> &job);

/* One scanline part of header h, whose compression is ZIP or ZIPS, written
 * from bands of floats given channel by channel, in the order of spec.names
 * (the file keeps the header's, sorted by name). Every call throws
 * on failure (std::runtime_error with the reason). */
class ZipPartWriter {
  public:
    ZipPartWriter();
    ~ZipPartWriter();
    void open(const std::string &path, const Imf::Header &h, const WriteSpec &spec);
    /* the next rows y0..y1-1 (from 0, the data window's top), any count */
    void write(int y0, int y1, const BandSrc *src);
    /* the chunk table, and the file closed */
    void close();

  private:
    struct Impl;
    std::unique_ptr<Impl> d_;
};

/* Rows of one scanline part of ZIP or ZIPS compression (no subsampled
 * channel) decoded here: each chunk's bytes as OpenEXR reads them from the
 * file (InputPart::rawPixelDataToBuffer), inflated, and the chosen
 * channels converted to float straight into their destinations. Throws
 * std::runtime_error on a damaged chunk. */
class ZipPartReader {
  public:
    ZipPartReader(Imf::InputPart &in, const Imf::Header &h);
    ~ZipPartReader();
    /* rows y0..y1-1 (0 = the data window's top) of the header's channels
     * names[k] into dst[k] */
    void read(int y0, int y1, const std::string *names, const BandDst *dst, size_t n);

  private:
    struct Impl;
    std::unique_ptr<Impl> d_;
};

} // namespace ewio
