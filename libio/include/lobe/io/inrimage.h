#pragma once
//! \file
//! \brief INRIMAGE-4 reading (read only): the format of CGAL's Mesh_3 example images, such as the
//! labelled liver `liver.inr.gz`. A text header of 256-byte blocks ("#INRIMAGE-4#{" ...
//! "##}") with XDIM/YDIM/ZDIM, VDIM, VX/VY/VZ, TYPE, PIXSIZE and CPU, then the voxels, x fastest;
//! the whole file may be gzipped. The format stores no origin nor orientation: the image is
//! placed at the origin with the identity direction, as CGAL reads it.

#include "lobe/core/any_image.h"

#include <filesystem>

namespace lobe::io {

//! Reads a scalar INRIMAGE-4 file (`.inr` or `.inr.gz`): unsigned or signed fixed-point of 8,
//! 16 or 32 bits, or float of 32 or 64 bits, in either byte order (CPU=decm, pc, alpha: little
//! endian; sun, sgi: big endian).
//! \throw core::IoError if the file cannot be opened. \throw core::InvalidInputError naming the
//! file for a bad or truncated header, a vector image (VDIM > 1), an unsupported type or
//! truncated data.
core::AnyImage read_inrimage(const std::filesystem::path& path);

} // namespace lobe::io
