#pragma once
// HDF5's shuffle, deflate and Fletcher-32 filters, run outside HDF5 so that the chunks of a large
// dataset can be filtered on every core (HDF5 1.10 filters one chunk at a time on one thread) and
// then stored with H5Dwrite_chunk. The bytes are exactly those HDF5's own pipeline writes
// (tests/io/hdf5_test.cpp compares them chunk by chunk), so any HDF5 reader decodes them.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace lobe::io::detail {

//! HDF5's shuffle filter: byte k of every element goes to the k-th plane of `out`.
//! `bytes` is a multiple of `element_size`; `out` holds `bytes` bytes.
void shuffle_bytes(const unsigned char* in, unsigned char* out, std::size_t bytes, std::size_t element_size);

//! The inverse of shuffle_bytes.
void unshuffle_bytes(const unsigned char* in, unsigned char* out, std::size_t bytes, std::size_t element_size);

//! Inflates a zlib stream of `in_bytes` into exactly `out_bytes`; false if the stream is corrupt
//! or does not decode to exactly that many bytes.
bool inflate_exactly(const unsigned char* in, std::size_t in_bytes, unsigned char* out, std::size_t out_bytes);

//! Fletcher-32 as HDF5 computes it (H5_checksum_fletcher32, not part of HDF5's public API):
//! big-endian 16-bit words, both sums folded every 360 words, an odd last byte as a high byte.
std::uint32_t fletcher32(const unsigned char* data, std::size_t bytes);

//! One chunk through the pipeline a dataset declares: shuffle (if element_size > 1) and deflate
//! at `gzip_level` when gzip_level > 0, then the Fletcher-32 checksum appended little-endian when
//! `checksum`. Returns false (and leaves `out` unspecified) only if zlib fails.
bool filter_chunk(const unsigned char* chunk, std::size_t bytes, std::size_t element_size, int gzip_level,
                  bool checksum, std::vector<unsigned char>& scratch, std::vector<unsigned char>& out);

//! The inverse of filter_chunk for a stored chunk of `stored_bytes`: checks and strips the
//! checksum when `checksum`, inflates when `deflate`, unshuffles when `shuffle` (which HDF5 only
//! ever pairs with deflate here). Leaves exactly `chunk_bytes` bytes in `out`; false if the
//! checksum fails or the stored bytes do not decode to exactly that many.
bool unfilter_chunk(const unsigned char* stored, std::size_t stored_bytes, std::size_t chunk_bytes,
                    std::size_t element_size, bool shuffle, bool deflate, bool checksum,
                    std::vector<unsigned char>& scratch, std::vector<unsigned char>& out);

//! The chunk grid of a row-major array of rank 1-3, padded to rank 3 with leading ones so that
//! one loop nest serves vectors, tables and volumes. Chunks are numbered x fastest, as HDF5's
//! own chunk index orders them.
struct ChunkGrid {
    std::array<std::size_t, 3> dims{1, 1, 1}, chunk{1, 1, 1}, grid{1, 1, 1};
    int rank = 0;

    //! `dims` and `chunk` hold `rank` entries, outermost first; no chunk extent may be 0.
    ChunkGrid(const unsigned long long* dims_in, const unsigned long long* chunk_in, int rank_in);

    std::size_t count() const { return grid[0] * grid[1] * grid[2]; }
    std::size_t chunk_values() const { return chunk[0] * chunk[1] * chunk[2]; }
    //! The first element of chunk `c`, in the padded coordinates.
    std::array<std::size_t, 3> origin(std::size_t c) const;
    //! The number of the chunk whose first element is `origin`.
    std::size_t index(const std::array<std::size_t, 3>& origin) const;
    //! Whether the chunk at `origin` reaches past the array (an edge chunk HDF5 pads).
    bool partial(const std::array<std::size_t, 3>& origin) const;
    //! Calls f(array_offset, chunk_offset, n) for each row of n elements the chunk at `origin`
    //! shares with the array (offsets in elements).
    template <class F>
    void rows(const std::array<std::size_t, 3>& origin, F&& f) const
    {
        const std::size_t nz = std::min(chunk[0], dims[0] - origin[0]), ny = std::min(chunk[1], dims[1] - origin[1]),
                          nx = std::min(chunk[2], dims[2] - origin[2]);
        for (std::size_t z = 0; z < nz; ++z)
            for (std::size_t y = 0; y < ny; ++y)
                f(((origin[0] + z) * dims[1] + origin[1] + y) * dims[2] + origin[2], (z * chunk[1] + y) * chunk[2], nx);
    }
};

//! How many chunks one parallel batch filters: a few per thread, so that the filtered chunks
//! awaiting HDF5 stay a bounded amount of memory.
std::size_t chunk_batch();

} // namespace lobe::io::detail
