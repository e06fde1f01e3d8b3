#pragma once
//! \file
//! \brief DICOM series reading through GDCM: a folder, a list of files, or one (multi-frame)
//! file becomes one 3-D image with LPS geometry and rescaled values (see docs/formats/dicom.md).

#include "lobe/core/any_image.h"

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace lobe::io {

//! Which series to read.
struct DicomReadParams {
    std::string series_uid; //!< SeriesInstanceUID to read; empty = the only readable series present
};

//! A series as read: the image and what identifies it.
struct DicomSeries {
    //! Rescaled values (HU for CT): int16 when every RescaleSlope/Intercept is an integer and the
    //! rescaled values fit, else float32. Geometry in LPS mm: origin = ImagePositionPatient of the
    //! first slice along the normal, direction columns = row cosines, column cosines, normal.
    core::AnyImage image;
    std::string series_uid;                   //!< SeriesInstanceUID (empty when the files carry none)
    std::string modality;                     //!< Modality (0008,0060), e.g. "CT"
    std::string description;                  //!< SeriesDescription (0008,103E)
    std::vector<std::filesystem::path> files; //!< the files read, in slice order (along the normal)
    std::vector<std::string> notes; //!< non-fatal remarks: skipped files, series passed over, assumed geometry
};

//! One series found in a folder, without decoding its pixels.
struct DicomSeriesInfo {
    std::string series_uid;                   //!< SeriesInstanceUID (empty when the files carry none)
    std::string modality;                     //!< Modality (0008,0060)
    std::string description;                  //!< SeriesDescription (0008,103E)
    std::string series_number;                //!< SeriesNumber (0020,0011), as written
    int slices = 0;                           //!< frames in the series (one per single-frame file)
    std::array<int, 2> size{0, 0};            //!< columns x rows of the first file
    std::vector<std::filesystem::path> files; //!< the series' files, in name order
    std::string problem; //!< why its files cannot be read (e.g. colour), or empty if they seem readable
};

//! Lists the image series of a folder (or of one file) without decoding pixels; files that are
//! not DICOM images are skipped. \throw core::IoError if the path does not exist, holds no DICOM
//! image, or a DICOM file in it is truncated or unreadable; core::InvalidInputError for a single
//! file that is DICOM but holds no image.
std::vector<DicomSeriesInfo> list_dicom_series(const std::filesystem::path& folder_or_file);

//! Reads one DICOM series from a folder (its files, not its subfolders; files that are not DICOM
//! images are skipped) or from a single, possibly multi-frame, file. Without a series_uid the
//! folder must hold one readable series; series lobe cannot read (e.g. colour screenshots) are
//! passed over with a note.
//! \param folder_or_file a folder of slice files or one DICOM file
//! \param params         which series, when the folder holds several
//! \throw core::IoError for a missing path, a folder without DICOM images, or a truncated,
//!        corrupt or undecodable file (even one of another series: its series is unknown);
//!        core::InvalidInputError for inconsistent or unsupported content: several series and
//!        no series_uid (the message lists them), duplicate slice positions, non-uniform
//!        spacing, slices stacked off their normal or differing in orientation, size or pixel
//!        spacing, colour or 1-bit pixels. Messages name the file or folder and the problem.
DicomSeries read_dicom_series(const std::filesystem::path& folder_or_file, const DicomReadParams& params = {});

//! Reads one series from an explicit list of files. Every file must be a DICOM image; if they
//! belong to several series, params.series_uid chooses one (else core::InvalidInputError).
//! \throw as read_dicom_series.
DicomSeries read_dicom_files(const std::vector<std::filesystem::path>& files, const DicomReadParams& params = {});

} // namespace lobe::io
