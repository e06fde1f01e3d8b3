#pragma once
// HDF5's shuffle, deflate and Fletcher-32 filters, run outside HDF5 so that the chunks of a large
// dataset can be filtered on every core (HDF5 1.10 filters one chunk at a time on one thread) and
// then stored with H5Dwrite_chunk. The bytes are exactly those HDF5's own pipeline writes
// (tests/io/hdf5_test.cpp compares them chunk by chunk), so any HDF5 reader decodes them.

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

} // namespace lobe::io::detail
