#pragma once
// Synthetic test inputs built in code.

#include "lobe/core/image3d.h"

#include <limits>
#include <random>
#include <type_traits>

namespace lobe::test {

//! An image of random values over T's whole range, seeded. The first voxels hold T's extremes
//! (byte-order and sign bugs) and, for floating T, NaN, +-infinity, -0 and a denormal (any
//! "cleaning" of float data); so needs at least 7 voxels.
template <class T>
core::Image3D<T> random_image(const core::ImageGeometry& g, unsigned seed)
{
    core::Image3D<T> img(g);
    std::mt19937 rng(seed);
    for (auto& v : img.data) {
        if constexpr (std::is_floating_point_v<T>)
            v = static_cast<T>(std::uniform_real_distribution<double>(-1e4, 1e4)(rng));
        else
            v = static_cast<T>(std::uniform_int_distribution<long long>(std::numeric_limits<T>::lowest(),
                                                                        std::numeric_limits<T>::max())(rng));
    }
    // Extremes show byte-order and sign bugs; NaN, infinities, -0 and a denormal show any
    // "cleaning" of float data (nifti_clib's own loader turns NaN into 0).
    img.data[0] = std::numeric_limits<T>::lowest();
    img.data[1] = std::numeric_limits<T>::max();
    if constexpr (std::is_floating_point_v<T>) {
        img.data[2] = std::numeric_limits<T>::quiet_NaN();
        img.data[3] = std::numeric_limits<T>::infinity();
        img.data[4] = -std::numeric_limits<T>::infinity();
        img.data[5] = static_cast<T>(-0.0);
        img.data[6] = std::numeric_limits<T>::denorm_min();
    }
    return img;
}

} // namespace lobe::test
