#pragma once
//! \file
//! \brief Triangle surface export and import through assimp, for viewers such as 3D Slicer,
//! MeshLab, ParaView and web viewers.
//!
//! Formats, chosen by the (case-insensitive) extension:
//!   .stl  binary STL           float32 coordinates, no shared vertices (one triple per triangle)
//!   .obj  Wavefront OBJ        text, no .mtl material file
//!   .ply  binary PLY           little-endian, float32 coordinates, shared vertices
//!   .gltf glTF 2 + .bin        JSON plus a binary buffer named after the file (mesh.gltf -> mesh.bin)
//!   .glb  glTF 2 binary        one file
//! assimp keeps coordinates in float32 whatever the format (Debian's build has no
//! ASSIMP_DOUBLE_PRECISION), so a round trip restores positions to float32 precision (relative
//! error below 6e-8 per coordinate). The HDF5 container is the lossless store; these files are
//! for viewing. Coordinates are written as they are (mm, LPS); no axis conversion.

#include "lobe/core/errors.h"
#include "lobe/core/tri_mesh.h"

#include <filesystem>

namespace lobe::io {

//! Writes a surface in the format its extension names, atomically: everything is written into a
//! temporary folder beside `path` and moved into place only when complete (for .gltf the .bin
//! first, then the .gltf), so a failed run leaves nothing behind.
//! \param path target file; its directory must exist
//! \param mesh non-empty, every index in range, no repeated vertex in a triangle, finite coordinates [mm]
//! \throw core::InvalidInputError for an unknown extension or a malformed mesh (checked before
//!        anything is written); core::IoError if writing fails
void write_surface(const std::filesystem::path& path, const core::TriMesh& mesh);

//! Reads a triangle surface from any file assimp reads (STL, OBJ, PLY, glTF, OFF, ...). Node
//! transforms are applied, polygons triangulated, points and lines dropped, all meshes merged,
//! and vertices at exactly the same position joined, so that a file written by write_surface()
//! comes back with its topology (STL stores none). Triangles whose corners coincide after the
//! join are dropped. Triangle order and winding are kept.
//! \throw core::IoError if the file is missing or assimp cannot read it;
//!        core::InvalidInputError if it holds no triangles or too many
core::TriMesh read_surface(const std::filesystem::path& path);

} // namespace lobe::io
