#pragma once
//! \file
//! \brief NIfTI-1 .nii / .nii.gz reading and writing (placeholder; the NIfTI work fills it in).

#include "lobe/core/any_image.h"

#include <filesystem>

namespace lobe::io {

//! Reads a NIfTI-1 image; geometry is converted from NIfTI's RAS to LPS.
core::AnyImage read_nifti(const std::filesystem::path& path);

//! Writes a NIfTI-1 image (.nii or .nii.gz by extension), atomically.
void write_nifti(const std::filesystem::path& path, const core::AnyImage& image);

} // namespace lobe::io
