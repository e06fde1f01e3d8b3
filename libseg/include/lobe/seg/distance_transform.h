#pragma once
//! \file
//! \brief Distance transforms: exact Euclidean (anisotropic, mm), signed distance of a mask,
//! and the exact chessboard distance (voxels) the CDSG pressure uses.

#include "lobe/core/image3d.h"

#include <cstdint>

namespace lobe::seg {

//! Exact Euclidean distance [mm] from every voxel centre to the nearest voxel centre where
//! `features` is non-zero (0 on features), honouring anisotropic spacing. Separable lower-
//! envelope algorithm (Felzenszwalb & Huttenlocher 2012), O(n) per line. Voxels of an image
//! without any feature get +infinity.
core::ImageF euclidean_distance(const core::LabelImage3D& features);

//! Signed distance [mm] to the boundary of `mask` (non-zero = inside): negative inside,
//! positive outside, with the zero level set half a voxel outside the boundary voxels (so
//! that `phi < 0` reproduces the mask exactly). Exact up to that half-voxel convention.
core::ImageF signed_distance(const core::LabelImage3D& mask);

//! Exact chessboard (L-infinity) distance in voxels from every voxel to the nearest non-zero
//! voxel of `features`, max(|di|, |dj|, |dk|), by two raster passes; -1 where there is no feature.
core::Image3D<std::int32_t> chessboard_distance(const core::LabelImage3D& features);

} // namespace lobe::seg
