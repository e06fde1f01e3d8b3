#pragma once
//! \file
//! \brief Reading and writing an image in any supported format, chosen from the path.
//!
//! | path                          | format                         | read | write |
//! |-------------------------------|--------------------------------|------|-------|
//! | `*.mhd`, `*.mha`              | MetaImage (metaimage.h)        | yes  | yes   |
//! | `*.nii`, `*.nii.gz`           | NIfTI-1 (nifti.h)              | yes  | yes   |
//! | `*.h5`, `*.hdf5`              | lobe HDF5 container (hdf5.h)   | yes  | yes   |
//! | a folder, `*.dcm`, `*.dicom`  | DICOM series (dicom.h)         | yes  | no    |
//! | `*.inr`, `*.inr.gz`           | INRIMAGE-4 (inrimage.h)        | yes  | no    |

#include "lobe/core/any_image.h"

#include <filesystem>
#include <string>

namespace lobe::io {

enum class ImageFormat { MetaImage, Nifti, Hdf5, Dicom, Inrimage };

//! Short name of a format ("MetaImage", "NIfTI", "HDF5", "DICOM", "INRIMAGE").
const char* format_name(ImageFormat format);

//! The format a path names, from its extension (or DICOM for a folder).
//! \throw core::InvalidInputError for an unknown extension, naming the supported ones.
ImageFormat image_format(const std::filesystem::path& path);

//! Reads an image in any supported format; geometry is LPS mm whatever the format.
core::AnyImage read_image(const std::filesystem::path& path);

//! Writes an image in the format its extension names, atomically.
//! \throw core::InvalidInputError for DICOM (read only) or an unknown extension.
void write_image(const std::filesystem::path& path, const core::AnyImage& image);

} // namespace lobe::io
