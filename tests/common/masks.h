#pragma once
// Small helpers on label masks shared by the segmentation tests.

#include "lobe/core/image3d.h"

#include <cstddef>

namespace lobe::test {

//! The number of non-zero voxels of `m`.
inline std::size_t count(const core::LabelImage3D& m)
{
    std::size_t n = 0;
    for (auto v : m.data)
        n += v != 0;
    return n;
}

} // namespace lobe::test
