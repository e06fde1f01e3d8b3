#pragma once
//! \file
//! \brief VectorField: a vector per voxel on an image grid (GVF, DSG and distance-transform
//! fields, level-set advection), one component image per axis.

#include "lobe/core/image3d.h"

#include <array>

namespace lobe::seg {

//! Components along the image axes i, j, k (not physical x, y, z: for a rotated grid the
//! field lives in index space), in the units of whatever the field means (e.g. mm per unit
//! time for a speed, or 1/mm for a gradient). A 2-D field keeps z zero-filled.
struct VectorField {
    std::array<core::ImageF, 3> c; //!< c[0], c[1], c[2]: components along i, j, k; same grid

    VectorField() = default;
    explicit VectorField(const core::ImageGeometry& g) : c{core::ImageF(g, 0.f), core::ImageF(g, 0.f), core::ImageF(g, 0.f)} {}

    const core::ImageGeometry& geometry() const { return c[0]; }
    bool empty() const { return c[0].data.empty(); }
};

} // namespace lobe::seg
