#include "detail/chunk_filters.h"

#include <zlib.h>

#include <algorithm>

namespace lobe::io::detail {

void shuffle_bytes(const unsigned char* in, unsigned char* out, std::size_t bytes, std::size_t element_size)
{
    const std::size_t n = bytes / element_size;
    for (std::size_t k = 0; k < element_size; ++k) {
        unsigned char* plane = out + k * n;
        const unsigned char* src = in + k;
        for (std::size_t i = 0; i < n; ++i)
            plane[i] = src[i * element_size];
    }
}

void unshuffle_bytes(const unsigned char* in, unsigned char* out, std::size_t bytes, std::size_t element_size)
{
    const std::size_t n = bytes / element_size;
    for (std::size_t k = 0; k < element_size; ++k) {
        const unsigned char* plane = in + k * n;
        unsigned char* dst = out + k;
        for (std::size_t i = 0; i < n; ++i)
            dst[i * element_size] = plane[i];
    }
}

bool inflate_exactly(const unsigned char* in, std::size_t in_bytes, unsigned char* out, std::size_t out_bytes)
{
    uLongf n = static_cast<uLongf>(out_bytes);
    return uncompress(out, &n, in, static_cast<uLong>(in_bytes)) == Z_OK && n == out_bytes;
}

std::uint32_t fletcher32(const unsigned char* data, std::size_t bytes)
{
    std::size_t words = bytes / 2;
    std::uint32_t sum1 = 0, sum2 = 0;
    while (words > 0) {
        // 360 words is the most the 32-bit sums take before they can overflow.
        std::size_t n = std::min<std::size_t>(words, 360);
        words -= n;
        for (; n > 0; --n, data += 2) {
            sum1 += (std::uint32_t(data[0]) << 8) | std::uint32_t(data[1]);
            sum2 += sum1;
        }
        sum1 = (sum1 & 0xffff) + (sum1 >> 16);
        sum2 = (sum2 & 0xffff) + (sum2 >> 16);
    }
    if (bytes % 2 != 0) {
        sum1 += std::uint32_t(*data) << 8;
        sum2 += sum1;
        sum1 = (sum1 & 0xffff) + (sum1 >> 16);
        sum2 = (sum2 & 0xffff) + (sum2 >> 16);
    }
    sum1 = (sum1 & 0xffff) + (sum1 >> 16);
    sum2 = (sum2 & 0xffff) + (sum2 >> 16);
    return (sum2 << 16) | sum1;
}

bool filter_chunk(const unsigned char* chunk, std::size_t bytes, std::size_t element_size, int gzip_level,
                  bool checksum, std::vector<unsigned char>& scratch, std::vector<unsigned char>& out)
{
    if (gzip_level > 0) {
        const unsigned char* src = chunk;
        if (element_size > 1 && bytes >= 2 * element_size) {
            scratch.resize(bytes);
            shuffle_bytes(chunk, scratch.data(), bytes, element_size);
            src = scratch.data();
        }
        // compress2 with the level HDF5's deflate filter passes; the same call gives the same bytes.
        uLongf n = compressBound(static_cast<uLong>(bytes));
        out.resize(n + 4);
        if (compress2(out.data(), &n, src, static_cast<uLong>(bytes), gzip_level) != Z_OK)
            return false;
        out.resize(n);
    } else {
        out.assign(chunk, chunk + bytes);
    }
    if (checksum) {
        const std::uint32_t f = fletcher32(out.data(), out.size());
        for (int b = 0; b < 4; ++b)
            out.push_back(static_cast<unsigned char>(f >> (8 * b)));
    }
    return true;
}

} // namespace lobe::io::detail
