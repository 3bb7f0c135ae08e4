/*
 * exr_zip.h — what the EXR codec does itself, for parts of ZIP or ZIPS
 * compression (internal to nodes/io): their chunks inflated and deflated
 * with libdeflate, where Debian 12's OpenEXR (3.1) goes through zlib at a
 * third of the speed (exr_zip_writer.cpp gives the figures). OpenEXR still
 * reads and writes the headers and chunk tables, and every other
 * compression (exr_codec.cpp). Also the conversions between floats and
 * the file's pixel types that both paths share.
 */
#pragma once

#include "codec.h"

#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>

#include <cstdint>
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

/* One scanline part of header h, whose compression is ZIP or ZIPS, written
 * from bands of interleaved floats whose channels are spec.names (in that
 * order; the file keeps the header's, sorted by name). Every call throws
 * on failure (std::runtime_error with the reason). */
class ZipPartWriter {
  public:
    ZipPartWriter();
    ~ZipPartWriter();
    void open(const std::string &path, const Imf::Header &h, const WriteSpec &spec);
    /* the next rows y0..y1-1 (from 0, the data window's top), any count */
    void write(int y0, int y1, const float *px);
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
