#pragma once
//! \file
//! \brief Limits every lobe reader enforces before allocating memory for a file's content.

#include <cstddef>

namespace lobe::io {

//! Largest image any reader accepts: 2^31 voxels (e.g. 1024 x 1024 x 2048), 4 GiB as int16.
//! A header asking for more is treated as corrupt rather than allocated.
inline constexpr std::size_t kMaxVoxels = std::size_t(1) << 31;

//! Largest mesh any reader or writer accepts: 2^28 vertices, triangles or tets. A mesh with
//! more is a corrupt header, not a liver.
inline constexpr std::size_t kMaxMeshElements = std::size_t(1) << 28;

} // namespace lobe::io
