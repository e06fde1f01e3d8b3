#pragma once
// Analytic label volumes for the meshing tests: spheres, boxes, painted on a grid by voxel centre.

#include "lobe/core/image3d.h"

#include <cmath>
#include <cstdint>

namespace lobe::test {

inline core::LabelImage3D empty_labels(int n, double spacing = 1.0, core::Vec3 origin = {})
{
    core::ImageGeometry g;
    g.size = {n, n, n};
    g.spacing = {spacing, spacing, spacing};
    g.origin = {origin.x, origin.y, origin.z};
    return core::LabelImage3D(g, 0);
}

//! Sets `label` on voxels whose centre (physical) lies within `r` mm of `c`.
inline void paint_sphere(core::LabelImage3D& img, const core::Vec3& c, double r, std::uint8_t label)
{
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < img.size[1]; ++j)
            for (int i = 0; i < img.size[0]; ++i)
                if (core::distance(img.index_to_physical(i, j, k), c) <= r)
                    img.at(i, j, k) = label;
}

//! Sets `label` on voxels whose centre lies in the box [lo, hi] (physical, mm).
inline void paint_box(core::LabelImage3D& img, const core::Vec3& lo, const core::Vec3& hi, std::uint8_t label)
{
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < img.size[1]; ++j)
            for (int i = 0; i < img.size[0]; ++i) {
                const auto p = img.index_to_physical(i, j, k);
                if (p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z)
                    img.at(i, j, k) = label;
            }
}

inline std::int64_t count_label(const core::LabelImage3D& img, std::uint8_t label)
{
    std::int64_t n = 0;
    for (auto v : img.data)
        n += v == label;
    return n;
}

} // namespace lobe::test
