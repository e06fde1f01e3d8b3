#pragma once
// Reading lseg's image inputs: a lobe container (.h5) by item name, anything else through libio.

#include "lobe/core/any_image.h"
#include "lobe/io/hdf5.h"
#include "lobe/io/image_io.h"

#include <filesystem>
#include <string>

namespace lobe::lseg {

//! The image at `path`: item `h5_name` of a .h5 container, or a MetaImage, NIfTI or DICOM folder.
inline core::AnyImage read_any(const std::filesystem::path& path, const std::string& h5_name)
{
    if (io::image_format(path) == io::ImageFormat::Hdf5)
        return io::read_hdf5_image(path, h5_name);
    return io::read_image(path);
}

} // namespace lobe::lseg
