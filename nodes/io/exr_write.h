/*
 * exr_write.h — what the EXR codec's two part writers share (internal to
 * nodes/io): the conversion of floats to the file's pixel types, and the
 * writer of ZIP and ZIPS parts (exr_zip_writer.cpp), which deflates the
 * chunks itself. Every other compression goes through OpenEXR's
 * Imf::OutputFile (exr_codec.cpp).
 */
#pragma once

#include "codec.h"

#include <OpenEXR/ImfHeader.h>

#include <cstdint>
#include <memory>

namespace ewio {

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

} // namespace ewio
