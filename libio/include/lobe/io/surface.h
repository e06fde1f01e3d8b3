#pragma once
//! \file
//! \brief Surface export and import through assimp (placeholder; the surface work fills it in).

#include "lobe/core/tri_mesh.h"

#include <filesystem>

namespace lobe::io {

//! Writes a surface as STL, OBJ, PLY or glTF (chosen by extension), atomically.
void write_surface(const std::filesystem::path& path, const core::TriMesh& mesh);

//! Reads a triangle surface from any format assimp reads.
core::TriMesh read_surface(const std::filesystem::path& path);

} // namespace lobe::io
