#pragma once
// The shape memory file of lseg train: a lobe HDF5 container (docs/file-format.md) holding the
// learnt tables as two float64 images, and the provenance of the run that trained it
// (schema: docs/algorithms/shape_memory.md, "File").

#include "lobe/io/hdf5.h"
#include "lobe/seg/shape_memory.h"

#include <filesystem>

namespace lobe::lseg {

//! Version of the shape memory layout inside the container (/images/shape_summary[0]).
inline constexpr int kShapeFileVersion = 1;

//! Writes `memory` to `path` atomically (temporary file renamed on commit), with `provenance`.
//! \throw core::IoError / core::InvalidInputError naming the file
void write_shape_memory(const std::filesystem::path& path, const seg::ShapeMemory& memory,
                        const io::Provenance& provenance);

//! Reads a file written by write_shape_memory. \throw core::IoError (missing, not HDF5) or
//! core::InvalidInputError naming the file and what is wrong (not a shape memory, a newer
//! layout, tables of the wrong size, non-finite values)
seg::ShapeMemory read_shape_memory(const std::filesystem::path& path);

} // namespace lobe::lseg
