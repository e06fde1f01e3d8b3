#pragma once
//! \file
//! \brief MetaImage (.mhd + data file, or .mha) reading and writing.
//!
//! Supports NDims 2 and 3; MET_UCHAR, CHAR, SHORT, USHORT, INT, UINT, FLOAT, DOUBLE; both byte
//! orders; zlib-compressed data (CompressedData = True); TransformMatrix, Offset (alias Position,
//! Origin) and ElementSpacing; ElementDataFile = LOCAL or a relative or absolute file name;
//! HeaderSize (including -1, "data at the end"); ElementNumberOfChannels; ASCII data
//! (BinaryData = False). Not supported, with a clear error: ElementDataFile = LIST or a
//! file-name pattern. See docs/formats/metaimage.md for the field-by-field mapping.
//!
//! Geometry follows ITK: TransformMatrix lists the image axes one after another (axis 0 first),
//! i.e. element (r * NDims + c) is component c of axis r; Offset is the physical position of
//! voxel (0,0,0).

#include "lobe/core/any_image.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lobe::io {

//! Everything a MetaImage header says, already validated.
struct MetaImageHeader {
    int ndims = 3;                            //!< 2 or 3 (a 2-D image has size[2] == 1)
    core::ImageGeometry geometry;             //!< size, spacing, origin, direction (3-D)
    core::PixelType pixel_type = core::PixelType::UInt8;
    int channels = 1;                         //!< ElementNumberOfChannels
    bool big_endian = false;                  //!< BinaryDataByteOrderMSB / ElementByteOrderMSB
    bool binary = true;                       //!< BinaryData (false: ASCII numbers)
    bool compressed = false;                  //!< CompressedData (zlib)
    std::int64_t compressed_size = -1;        //!< CompressedDataSize, -1 if absent
    std::int64_t header_size = 0;             //!< HeaderSize: bytes to skip, -1 = data at the end
    bool local = true;                        //!< ElementDataFile = LOCAL
    std::filesystem::path data_file;          //!< resolved data file when !local
    std::size_t data_offset = 0;              //!< LOCAL only: byte offset of the data in the file
};

//! Parses a header held in memory. `name` is used in error messages and to resolve a relative
//! ElementDataFile. \throw core::InvalidInputError naming `name` and the field at fault.
MetaImageHeader parse_metaimage_header(std::string_view text, const std::filesystem::path& name);

//! Reads and validates the header of a .mhd/.mha file without reading its data.
MetaImageHeader read_metaimage_header(const std::filesystem::path& path);

//! Reads a single-channel MetaImage. \throw core::IoError (missing/truncated files),
//! core::InvalidInputError (bad header; more than one channel: use read_metaimage_channels).
core::AnyImage read_metaimage(const std::filesystem::path& path);

//! Reads a MetaImage with any number of channels; one image per channel.
std::vector<core::AnyImage> read_metaimage_channels(const std::filesystem::path& path);

//! Decodes a complete MetaImage held in memory (ElementDataFile must be LOCAL); the whole
//! reading path without the file system, used by the fuzzer and by tests.
std::vector<core::AnyImage> decode_metaimage(std::string_view bytes, const std::filesystem::path& name);

struct MetaImageWriteParams {
    bool compress = false;  //!< zlib-compress the data (CompressedData = True)
    int compression_level = 1; //!< zlib level 1 (fast) .. 9 (small); 1 writes CT 6x faster than 6
                               //!< for files ~2% larger (docs/benchmarks.md)
    int ndims = 0;          //!< 2 or 3; 0 = 2 when the image is a single slice at z = 0 with a
                            //!< z-aligned third axis, else 3
};

//! Writes `image` as .mha (header and data in one file) or .mhd (+ .raw, or .zraw when
//! compressed), chosen by the extension, atomically: nothing is left behind on failure.
//! \throw core::InvalidInputError for an invalid geometry or extension, core::IoError on failure.
void write_metaimage(const std::filesystem::path& path, const core::AnyImage& image,
                     const MetaImageWriteParams& params = {});

} // namespace lobe::io
