/*
 * exr_zip_bytes.cpp — ZIP's byte transforms around deflate (exr_zip.h),
 * sixteen bytes at a time.
 *
 * Undoing the predictor is a running sum of bytes: written as the format
 * states it (each byte plus the one before, less 128) the loop carries one
 * dependency a byte, and it was two thirds of the reader's own time on a
 * multilayer frame, more than libdeflate's inflate. Here a block of 16 is
 * summed in four shifted adds, independent of the block before, and only
 * the block's carry (the previous block's last byte, broadcast) chains the
 * blocks: one add a block. The split into even and odd bytes and its
 * inverse are byte unpacks and packs. SSE2 is part of x86-64, so no
 * dispatch; other machines take the byte loops, which give the same bytes.
 */
#include "exr_zip.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace ewio {

#if defined(__SSE2__)
namespace {

/* every byte of v set to v's last byte */
inline __m128i last_byte(__m128i v) {
    __m128i x = _mm_srli_si128(v, 15);
    x = _mm_unpacklo_epi8(x, x);
    x = _mm_shufflelo_epi16(x, 0);
    return _mm_shuffle_epi32(x, 0);
}

inline __m128i load(const unsigned char *p) { return _mm_loadu_si128(reinterpret_cast<const __m128i *>(p)); }
inline void store(unsigned char *p, __m128i v) { _mm_storeu_si128(reinterpret_cast<__m128i *>(p), v); }

} // namespace
#endif

void zip_predict(unsigned char *t, size_t n) {
    /* from the end down, so that each byte's predecessor is still the
     * original when it is read */
    size_t end = n; /* bytes [1, end) still to do */
#if defined(__SSE2__)
    const __m128i bias = _mm_set1_epi8(char(-128));
    while (end >= 17) {
        const size_t i = end - 16;
        store(t + i, _mm_add_epi8(_mm_sub_epi8(load(t + i), load(t + i - 1)), bias));
        end = i;
    }
#endif
    for (size_t i = end; i-- > 1;) t[i] = (unsigned char)(t[i] - t[i - 1] + 128);
}

void zip_unpredict(unsigned char *t, size_t n) {
    size_t i = 1;
#if defined(__SSE2__)
    if (n > 16) {
        const __m128i bias = _mm_set1_epi8(char(-128));
        __m128i carry = _mm_set1_epi8(char(t[0]));
        for (; i + 16 <= n; i += 16) {
            __m128i d = _mm_add_epi8(load(t + i), bias);
            d = _mm_add_epi8(d, _mm_slli_si128(d, 1));
            d = _mm_add_epi8(d, _mm_slli_si128(d, 2));
            d = _mm_add_epi8(d, _mm_slli_si128(d, 4));
            d = _mm_add_epi8(d, _mm_slli_si128(d, 8));
            store(t + i, _mm_add_epi8(d, carry));
            carry = _mm_add_epi8(carry, last_byte(d));
        }
    }
#endif
    for (; i < n; i++) t[i] = (unsigned char)(t[i - 1] + t[i] - 128);
}

void zip_split(const unsigned char *raw, size_t n, unsigned char *t) {
    unsigned char *even = t, *odd = t + (n + 1) / 2;
    size_t i = 0;
#if defined(__SSE2__)
    const __m128i low = _mm_set1_epi16(0x00ff);
    for (; i + 32 <= n; i += 32) {
        const __m128i a = load(raw + i), b = load(raw + i + 16);
        store(even + i / 2, _mm_packus_epi16(_mm_and_si128(a, low), _mm_and_si128(b, low)));
        store(odd + i / 2, _mm_packus_epi16(_mm_srli_epi16(a, 8), _mm_srli_epi16(b, 8)));
    }
#endif
    for (; i + 1 < n; i += 2) {
        even[i / 2] = raw[i];
        odd[i / 2] = raw[i + 1];
    }
    if (n & 1) even[n / 2] = raw[n - 1];
}

void zip_merge(const unsigned char *even, const unsigned char *odd, size_t pairs, unsigned char *raw) {
    size_t k = 0;
#if defined(__SSE2__)
    for (; k + 16 <= pairs; k += 16) {
        const __m128i a = load(even + k), b = load(odd + k);
        store(raw + 2 * k, _mm_unpacklo_epi8(a, b));
        store(raw + 2 * k + 16, _mm_unpackhi_epi8(a, b));
    }
#endif
    for (; k < pairs; k++) {
        raw[2 * k] = even[k];
        raw[2 * k + 1] = odd[k];
    }
}

} // namespace ewio
