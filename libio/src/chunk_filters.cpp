#include "detail/chunk_filters.h"

#include <omp.h>
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

namespace {

// HDF5's shuffle filter leaves a chunk of one-byte elements, or of a single element, as it is.
bool shuffles(std::size_t bytes, std::size_t element_size)
{
    return element_size > 1 && bytes >= 2 * element_size;
}

} // namespace

bool filter_chunk(const unsigned char* chunk, std::size_t bytes, std::size_t element_size, int gzip_level,
                  bool checksum, std::vector<unsigned char>& scratch, std::vector<unsigned char>& out)
{
    if (gzip_level > 0) {
        const unsigned char* src = chunk;
        if (shuffles(bytes, element_size)) {
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

bool unfilter_chunk(const unsigned char* stored, std::size_t stored_bytes, std::size_t chunk_bytes,
                    std::size_t element_size, bool shuffle, bool deflate, bool checksum,
                    std::vector<unsigned char>& scratch, std::vector<unsigned char>& out)
{
    std::size_t n = stored_bytes;
    if (checksum) {
        if (n < 4)
            return false;
        n -= 4;
        const unsigned char* t = stored + n; // appended little-endian, as filter_chunk writes it
        const std::uint32_t expected =
            std::uint32_t(t[0]) | std::uint32_t(t[1]) << 8 | std::uint32_t(t[2]) << 16 | std::uint32_t(t[3]) << 24;
        if (fletcher32(stored, n) != expected)
            return false;
    }
    const bool unshuffle = shuffle && shuffles(chunk_bytes, element_size);
    std::vector<unsigned char>& plain = unshuffle ? scratch : out;
    plain.resize(chunk_bytes);
    if (deflate) {
        if (!inflate_exactly(stored, n, plain.data(), chunk_bytes))
            return false;
    } else {
        if (n != chunk_bytes)
            return false;
        std::copy_n(stored, n, plain.data());
    }
    if (unshuffle) {
        out.resize(chunk_bytes);
        unshuffle_bytes(scratch.data(), out.data(), chunk_bytes, element_size);
    }
    return true;
}

ChunkGrid::ChunkGrid(const unsigned long long* dims_in, const unsigned long long* chunk_in, int rank_in) : rank(rank_in)
{
    for (int a = 0; a < rank; ++a) {
        dims[static_cast<std::size_t>(3 - rank + a)] = static_cast<std::size_t>(dims_in[a]);
        chunk[static_cast<std::size_t>(3 - rank + a)] = static_cast<std::size_t>(chunk_in[a]);
    }
    for (std::size_t a = 0; a < 3; ++a)
        grid[a] = (dims[a] + chunk[a] - 1) / chunk[a];
}

std::array<std::size_t, 3> ChunkGrid::origin(std::size_t c) const
{
    return {c / (grid[1] * grid[2]) * chunk[0], c / grid[2] % grid[1] * chunk[1], c % grid[2] * chunk[2]};
}

std::size_t ChunkGrid::index(const std::array<std::size_t, 3>& o) const
{
    return (o[0] / chunk[0] * grid[1] + o[1] / chunk[1]) * grid[2] + o[2] / chunk[2];
}

bool ChunkGrid::partial(const std::array<std::size_t, 3>& o) const
{
    return o[0] + chunk[0] > dims[0] || o[1] + chunk[1] > dims[1] || o[2] + chunk[2] > dims[2];
}

std::size_t chunk_batch()
{
    return 4 * static_cast<std::size_t>(std::max(1, omp_get_max_threads()));
}

} // namespace lobe::io::detail
