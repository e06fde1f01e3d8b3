#pragma once
//! \file
//! \brief DICOM series reading through GDCM (placeholder; the DICOM work fills it in).

#include "lobe/core/any_image.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lobe::io {

struct DicomReadParams {
    std::string series_uid; //!< SeriesInstanceUID to read; empty = the folder's only series
};

struct DicomSeries {
    core::AnyImage image;          //!< rescaled values (HU for CT), LPS geometry
    std::string series_uid;
    std::string modality;
    std::string description;
    std::vector<std::filesystem::path> files; //!< slice files in the order used (along the normal)
};

//! Reads a DICOM series from a folder or a single file. \throw core::IoError, core::InvalidInputError
DicomSeries read_dicom_series(const std::filesystem::path& folder_or_file, const DicomReadParams& params = {});

//! Reads a series from an explicit list of files (all must belong to one series).
DicomSeries read_dicom_files(const std::vector<std::filesystem::path>& files, const DicomReadParams& params = {});

} // namespace lobe::io
