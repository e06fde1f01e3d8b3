#pragma once
// Small volume helpers shared by the vessel and tumour code: boxes, crops, connected
// components, trilinear sampling. Private to libseg (never installed).

#include "lobe/core/image3d.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace lobe::seg::detail {

//! An index box [lo, hi] (inclusive); empty when lo > hi on any axis.
struct Box {
    std::array<int, 3> lo{0, 0, 0};
    std::array<int, 3> hi{-1, -1, -1};
    bool empty() const { return lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]; }
    std::array<int, 3> size() const { return {hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1}; }
};

//! The bounding box of the non-zero voxels (empty if there are none).
template <class T>
Box bounding_box(const core::Image3D<T>& mask)
{
    Box b{{mask.size[0], mask.size[1], mask.size[2]}, {-1, -1, -1}};
    const int nx = mask.size[0];
    for (int k = 0; k < mask.size[2]; ++k)
        for (int j = 0; j < mask.size[1]; ++j) {
            // A row's first and last non-zero voxels are all it adds: scan in from both ends.
            const T* row = mask.data.data() + mask.index(0, j, k);
            const T* first = std::find_if(row, row + nx, [](T v) { return v != T{}; });
            if (first == row + nx)
                continue;
            int last = nx - 1;
            while (row[last] == T{})
                --last;
            const auto i = static_cast<int>(first - row);
            b.lo = {std::min(b.lo[0], i), std::min(b.lo[1], j), std::min(b.lo[2], k)};
            b.hi = {std::max(b.hi[0], last), std::max(b.hi[1], j), std::max(b.hi[2], k)};
        }
    return b;
}

//! `b` grown by `margin` voxels per axis, clipped to the grid `g`.
inline Box grown(const Box& b, const std::array<int, 3>& margin, const core::ImageGeometry& g)
{
    Box r = b;
    for (int a = 0; a < 3; ++a) {
        r.lo[a] = std::max(0, b.lo[a] - margin[a]);
        r.hi[a] = std::min(g.size[a] - 1, b.hi[a] + margin[a]);
    }
    return r;
}

//! Voxels covering `mm` along each axis (at least 1 if mm > 0).
inline std::array<int, 3> voxels_for(const core::ImageGeometry& g, double mm)
{
    std::array<int, 3> m{0, 0, 0};
    for (int a = 0; a < 3; ++a)
        m[a] = mm > 0 ? std::max(1, static_cast<int>(std::ceil(mm / g.spacing[a]))) : 0;
    return m;
}

//! The sub-image in box `b`, keeping its place in space.
template <class T>
core::Image3D<T> crop(const core::Image3D<T>& image, const Box& b)
{
    core::ImageGeometry g = image.geometry();
    const core::Vec3 o = image.index_to_physical(b.lo[0], b.lo[1], b.lo[2]);
    g.origin = {o.x, o.y, o.z};
    g.size = b.size();
    core::Image3D<T> out(g);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j) {
            const T* src = image.data.data() + image.index(b.lo[0], b.lo[1] + j, b.lo[2] + k);
            std::copy(src, src + g.size[0], out.data.data() + out.index(0, j, k));
        }
    return out;
}

//! Writes `part` (cropped at box `b`) back into `image`.
template <class T>
void paste(core::Image3D<T>& image, const core::Image3D<T>& part, const Box& b)
{
    for (int k = 0; k < part.size[2]; ++k)
        for (int j = 0; j < part.size[1]; ++j) {
            const T* src = part.data.data() + part.index(0, j, k);
            std::copy(src, src + part.size[0], image.data.data() + image.index(b.lo[0], b.lo[1] + j, b.lo[2] + k));
        }
}

//! Connected components of the non-zero voxels (26- or 6-connectivity): a component id per voxel
//! (-1 for background) and the voxel count of each component.
struct Components {
    std::vector<std::int32_t> id;
    std::vector<std::size_t> sizes;
};

template <class T>
Components connected_components(const core::Image3D<T>& mask, int connectivity = 26)
{
    Components c;
    c.id.assign(mask.data.size(), -1);
    const int nx = mask.size[0], ny = mask.size[1], nz = mask.size[2];
    std::vector<std::size_t> stack;
    for (std::size_t s = 0; s < mask.data.size(); ++s) {
        if (mask.data[s] == T{} || c.id[s] >= 0)
            continue;
        const auto label = static_cast<std::int32_t>(c.sizes.size());
        std::size_t count = 0;
        stack.push_back(s);
        c.id[s] = label;
        while (!stack.empty()) {
            const std::size_t v = stack.back();
            stack.pop_back();
            ++count;
            const int i = static_cast<int>(v % static_cast<std::size_t>(nx));
            const int j = static_cast<int>((v / static_cast<std::size_t>(nx)) % static_cast<std::size_t>(ny));
            const int k = static_cast<int>(v / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
            for (int dk = -1; dk <= 1; ++dk)
                for (int dj = -1; dj <= 1; ++dj)
                    for (int di = -1; di <= 1; ++di) {
                        const int d = std::abs(di) + std::abs(dj) + std::abs(dk);
                        if (d == 0 || (connectivity == 6 && d > 1) || (connectivity == 18 && d > 2))
                            continue;
                        const int ii = i + di, jj = j + dj, kk = k + dk;
                        if (ii < 0 || jj < 0 || kk < 0 || ii >= nx || jj >= ny || kk >= nz)
                            continue;
                        const std::size_t w = mask.index(ii, jj, kk);
                        if (mask.data[w] != T{} && c.id[w] < 0) {
                            c.id[w] = label;
                            stack.push_back(w);
                        }
                    }
        }
        c.sizes.push_back(count);
    }
    return c;
}

//! Trilinear interpolation of `image` at the continuous index (x, y, z), clamped to the grid.
inline float sample_trilinear(const core::ImageF& image, double x, double y, double z)
{
    const double cx = std::clamp(x, 0.0, double(image.size[0] - 1));
    const double cy = std::clamp(y, 0.0, double(image.size[1] - 1));
    const double cz = std::clamp(z, 0.0, double(image.size[2] - 1));
    const int i0 = std::min(static_cast<int>(cx), image.size[0] - 1), j0 = std::min(static_cast<int>(cy), image.size[1] - 1),
              k0 = std::min(static_cast<int>(cz), image.size[2] - 1);
    const int i1 = std::min(i0 + 1, image.size[0] - 1), j1 = std::min(j0 + 1, image.size[1] - 1),
              k1 = std::min(k0 + 1, image.size[2] - 1);
    const double fx = cx - i0, fy = cy - j0, fz = cz - k0;
    auto v = [&](int i, int j, int k) { return static_cast<double>(image.at(i, j, k)); };
    const double c00 = v(i0, j0, k0) * (1 - fx) + v(i1, j0, k0) * fx;
    const double c10 = v(i0, j1, k0) * (1 - fx) + v(i1, j1, k0) * fx;
    const double c01 = v(i0, j0, k1) * (1 - fx) + v(i1, j0, k1) * fx;
    const double c11 = v(i0, j1, k1) * (1 - fx) + v(i1, j1, k1) * fx;
    const double c0 = c00 * (1 - fy) + c10 * fy, c1 = c01 * (1 - fy) + c11 * fy;
    return static_cast<float>(c0 * (1 - fz) + c1 * fz);
}

//! Validates an image: geometry and data size, naming `what`.
template <class T>
void check_image(const core::Image3D<T>& image, const std::string& what)
{
    core::validate_geometry(image, what);
    if (image.data.size() != image.voxel_count())
        throw core::InvalidInputError(what + ": holds " + std::to_string(image.data.size()) + " values for " +
                                      std::to_string(image.voxel_count()) + " voxels");
}

//! Validates a mask on the grid of `ref`, naming `what`.
template <class T>
void check_same_grid(const core::ImageGeometry& ref, const core::Image3D<T>& mask, const std::string& what)
{
    if (!core::same_grid(ref, mask) || mask.data.size() != ref.voxel_count())
        throw core::InvalidInputError(what + " is not on the image's grid");
}

//! The value at quantile q in [0, 1] of `v` (copied; v non-empty).
inline double quantile(std::vector<float> v, double q)
{
    if (v.empty())
        return 0.0;
    const auto n = static_cast<std::ptrdiff_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + n, v.end());
    return v[static_cast<std::size_t>(n)];
}

//! The q-quantile of an image's values, from a strided sample of at most about a million voxels
//! (a 512 x 512 x 200 CT would otherwise be copied whole).
inline double sampled_quantile(const core::ImageF& v, double q)
{
    const std::size_t n = v.data.size();
    const std::size_t stride = std::max<std::size_t>(1, n / (std::size_t(1) << 20));
    std::vector<float> sample;
    sample.reserve(n / stride + 1);
    for (std::size_t i = 0; i < n; i += stride)
        sample.push_back(v.data[i]);
    return quantile(std::move(sample), q);
}

//! The median of `v` and its robust sd, 1.4826 times the median absolute deviation (the sd of a
//! normal sample, unmoved by a minority of outliers). {0, 0} for an empty v.
inline std::pair<double, double> median_and_robust_sd(std::vector<float> v)
{
    const double median = quantile(v, 0.5);
    for (float& x : v)
        x = static_cast<float>(std::abs(static_cast<double>(x) - median));
    return {median, 1.4826 * quantile(std::move(v), 0.5)};
}

} // namespace lobe::seg::detail
