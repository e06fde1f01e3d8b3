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

//! Voxels of `m` outside `truth` (false positives), as a double for tolerance arithmetic.
inline double voxels_outside(const core::LabelImage3D& m, const core::LabelImage3D& truth)
{
    std::size_t n = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i)
        n += m.data[i] && !truth.data[i];
    return double(n);
}

//! Voxels of `truth` outside `m` (missed), as a double.
inline double voxels_missed(const core::LabelImage3D& m, const core::LabelImage3D& truth)
{
    std::size_t n = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i)
        n += !m.data[i] && truth.data[i];
    return double(n);
}

//! Voxels where `a` and `b` differ; masks of different sizes count as differing everywhere.
inline std::size_t voxels_differing(const core::LabelImage3D& a, const core::LabelImage3D& b)
{
    if (a.data.size() != b.data.size())
        return a.data.size() > b.data.size() ? a.data.size() : b.data.size();
    std::size_t n = 0;
    for (std::size_t i = 0; i < a.data.size(); ++i)
        n += a.data[i] != b.data[i];
    return n;
}

} // namespace lobe::test
