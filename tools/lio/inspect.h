#pragma once
// lio's reading and reporting: any image format, DICOM series choice, HDF5 container contents.

#include "common/cli.h"

#include "lobe/core/any_image.h"
#include "lobe/io/image_io.h"

#include <filesystem>
#include <string>

namespace lobe::lio {

//! Which image of an input to read.
struct Selection {
    std::string series_uid; //!< DICOM: SeriesInstanceUID (empty: the folder's only series)
    std::string item;       //!< HDF5: image or label volume name (empty: the only one)
    int volume = -1;        //!< NIfTI: volume of a 4-D series, 0-based along dim[4] (-1: the only one)
};

struct Loaded {
    core::AnyImage image;
    io::ImageFormat format = io::ImageFormat::MetaImage;
    std::string detail; //!< e.g. the DICOM series read
};

//! Reads one image of any supported input; DICOM notes go to `progress`.
Loaded load(const std::filesystem::path& path, const Selection& selection, const tools::Progress& progress);

//! `lio info`: prints geometry, type and range of one image, or, for a DICOM folder with several
//! series, an HDF5 container with several items or a NIfTI series of several volumes (and no
//! selection), what it holds.
int info(const std::filesystem::path& path, const Selection& selection, bool json, const tools::Progress& progress);

//! 3 decimals with trailing zeros dropped, one kept: 0.9765625 -> "0.977", 2 -> "2.0".
std::string short_number(double v);

} // namespace lobe::lio
