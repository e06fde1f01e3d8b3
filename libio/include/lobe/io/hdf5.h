#pragma once
//! \file
//! \brief The HDF5 pipeline container (placeholder; the HDF5 work fills it in).

#include "lobe/core/any_image.h"

#include <filesystem>
#include <string>

namespace lobe::io {

//! Reads image `name` (empty: the file's only image) from a lobe HDF5 container.
core::AnyImage read_hdf5_image(const std::filesystem::path& path, const std::string& name = {});

//! Writes a container holding one image named `name`, atomically, with its XDMF sidecar.
void write_hdf5_image(const std::filesystem::path& path, const core::AnyImage& image, const std::string& name = "image");

} // namespace lobe::io
