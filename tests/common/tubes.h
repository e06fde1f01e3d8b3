#pragma once
// Synthetic tubular shapes for the vessel tests: capsules rasterised with a one-voxel linear
// partial-volume ramp, on any grid.

#include "lobe/core/image3d.h"
#include "lobe/core/types.h"

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

namespace lobe::test {

//! A straight tube from a to b [mm] with radius r [mm].
struct Tube {
    core::Vec3 a, b;
    double r = 1;
};

//! Distance from p to the segment ab.
inline double distance_to_segment(const core::Vec3& p, const core::Vec3& a, const core::Vec3& b)
{
    const core::Vec3 d = b - a;
    const double dd = core::dot(d, d);
    const double t = dd > 0 ? std::clamp(core::dot(p - a, d) / dd, 0.0, 1.0) : 0.0;
    return core::distance(p, a + d * t);
}

//! Fraction of voxel (i, j, k) inside the union of the tubes: 1 inside, 0 outside, linear over a
//! ramp one finest-spacing wide centred on the wall (a cheap partial volume).
inline double tube_fraction(const core::ImageGeometry& g, int i, int j, int k, const std::vector<Tube>& tubes)
{
    const core::Vec3 p = g.index_to_physical(i, j, k);
    const double w = std::min({g.spacing[0], g.spacing[1], g.spacing[2]});
    double f = 0;
    for (const auto& t : tubes)
        f = std::max(f, std::clamp((t.r - distance_to_segment(p, t.a, t.b)) / w + 0.5, 0.0, 1.0));
    return f;
}

//! An image of `background` with the tubes at `background + contrast`, plus Gaussian noise.
inline core::ImageF tube_image(const core::ImageGeometry& g, const std::vector<Tube>& tubes, double background,
                               double contrast, double noise, unsigned seed = 1)
{
    core::ImageF img(g, 0.f);
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, noise > 0 ? noise : 1.0);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i)
                img.at(i, j, k) = static_cast<float>(background + contrast * tube_fraction(g, i, j, k, tubes) +
                                                     (noise > 0 ? n(rng) : 0.0));
    return img;
}

//! The voxels whose centre lies inside a tube.
inline core::LabelImage3D tube_mask(const core::ImageGeometry& g, const std::vector<Tube>& tubes)
{
    core::LabelImage3D m(g, 0);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const core::Vec3 p = g.index_to_physical(i, j, k);
                for (const auto& t : tubes)
                    if (distance_to_segment(p, t.a, t.b) <= t.r)
                        m.at(i, j, k) = 1;
            }
    return m;
}

//! A grid of the given size and spacing with its origin at 0.
inline core::ImageGeometry grid(std::array<int, 3> size, std::array<double, 3> spacing)
{
    core::ImageGeometry g;
    g.size = size;
    g.spacing = spacing;
    return g;
}

} // namespace lobe::test
