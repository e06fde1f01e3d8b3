#pragma once
//! \file
//! \brief Image3D<T>: a 3-D scalar image with ITK's geometry (origin, spacing, direction).
//!
//! The index (i, j, k) addresses data[i + size[0] * (j + size[1] * k)]: x runs fastest, as in
//! ITK, MetaImage and DICOM. The physical position (mm, LPS for medical data) of a voxel is
//!     p = origin + D * diag(spacing) * (i, j, k)^T,
//! where D = direction is a 3x3 matrix stored row-major whose *columns* are the image axes.
//! A 2-D image is a 3-D image with size[2] == 1.

#include "lobe/core/big_buffer.h"
#include "lobe/core/errors.h"
#include "lobe/core/types.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::core {

//! Size and placement of a voxel grid, in ITK's meaning.
struct ImageGeometry {
    std::array<int, 3> size{0, 0, 0};            //!< voxels along x, y, z
    std::array<double, 3> spacing{1.0, 1.0, 1.0}; //!< voxel size along each axis [mm]
    std::array<double, 3> origin{0.0, 0.0, 0.0};  //!< physical position of voxel (0,0,0) [mm]
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1}; //!< row-major, columns = axes

    //! Number of voxels (size_t so that 512 x 512 x 1000 does not overflow).
    std::size_t voxel_count() const
    {
        return static_cast<std::size_t>(size[0] > 0 ? size[0] : 0) *
               static_cast<std::size_t>(size[1] > 0 ? size[1] : 0) *
               static_cast<std::size_t>(size[2] > 0 ? size[2] : 0);
    }

    std::size_t index(int i, int j, int k) const
    {
        return static_cast<std::size_t>(i) +
               static_cast<std::size_t>(size[0]) *
                   (static_cast<std::size_t>(j) + static_cast<std::size_t>(size[1]) * static_cast<std::size_t>(k));
    }

    bool contains(int i, int j, int k) const
    {
        return i >= 0 && j >= 0 && k >= 0 && i < size[0] && j < size[1] && k < size[2];
    }

    //! Axis a of the direction matrix (column a), a unit vector for a valid geometry.
    Vec3 axis(int a) const { return {direction[a], direction[3 + a], direction[6 + a]}; }

    //! Physical position [mm] of a continuous index (voxel centres are at integers).
    Vec3 index_to_physical(const Vec3& ijk) const
    {
        Vec3 p{origin[0], origin[1], origin[2]};
        for (int a = 0; a < 3; ++a)
            p += axis(a) * (ijk[a] * spacing[a]);
        return p;
    }
    Vec3 index_to_physical(int i, int j, int k) const
    {
        return index_to_physical(Vec3{double(i), double(j), double(k)});
    }

    //! Continuous index of a physical position; the inverse of index_to_physical.
    //! \throw InvalidInputError if the direction matrix is singular.
    Vec3 physical_to_index(const Vec3& p) const
    {
        const auto& d = direction;
        const double det = d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) +
                           d[2] * (d[3] * d[7] - d[4] * d[6]);
        if (!(std::abs(det) > 1e-12))
            throw InvalidInputError("physical_to_index: the direction matrix is singular");
        // inverse(D) = adj(D) / det
        const std::array<double, 9> inv{
            (d[4] * d[8] - d[5] * d[7]) / det, (d[2] * d[7] - d[1] * d[8]) / det, (d[1] * d[5] - d[2] * d[4]) / det,
            (d[5] * d[6] - d[3] * d[8]) / det, (d[0] * d[8] - d[2] * d[6]) / det, (d[2] * d[3] - d[0] * d[5]) / det,
            (d[3] * d[7] - d[4] * d[6]) / det, (d[1] * d[6] - d[0] * d[7]) / det, (d[0] * d[4] - d[1] * d[3]) / det};
        const Vec3 q{p.x - origin[0], p.y - origin[1], p.z - origin[2]};
        Vec3 ijk;
        for (int r = 0; r < 3; ++r)
            ijk[r] = (inv[3 * r] * q.x + inv[3 * r + 1] * q.y + inv[3 * r + 2] * q.z) / spacing[r];
        return ijk;
    }
};

//! Why a geometry is invalid, or an empty string if it is valid: positive size, finite positive
//! spacing, finite origin, and a finite direction matrix whose columns are unit vectors
//! (to 1e-3) and that is not singular.
inline std::string geometry_problem(const ImageGeometry& g)
{
    for (int a = 0; a < 3; ++a) {
        if (g.size[a] <= 0)
            return "size along axis " + std::to_string(a) + " is " + std::to_string(g.size[a]) +
                   " (must be positive)";
        if (!std::isfinite(g.spacing[a]) || !(g.spacing[a] > 0))
            return "spacing along axis " + std::to_string(a) + " is " + std::to_string(g.spacing[a]) +
                   " (must be finite and positive)";
        if (!std::isfinite(g.origin[a]))
            return "origin is not finite";
    }
    for (double v : g.direction)
        if (!std::isfinite(v))
            return "direction matrix is not finite";
    for (int a = 0; a < 3; ++a)
        if (std::abs(norm(g.axis(a)) - 1.0) > 1e-3)
            return "direction axis " + std::to_string(a) + " is not a unit vector";
    const Vec3 c = cross(g.axis(0), g.axis(1));
    if (std::abs(dot(c, g.axis(2))) < 1e-3)
        return "direction matrix is singular";
    return {};
}

//! \throw InvalidInputError naming `what` (e.g. the file) if the geometry is invalid.
inline void validate_geometry(const ImageGeometry& g, const std::string& what)
{
    const std::string problem = geometry_problem(g);
    if (!problem.empty())
        throw InvalidInputError(what + ": invalid image geometry: " + problem);
}

//! True if both grids have the same size and, to `tol` mm (or `tol` for the direction
//! cosines), the same spacing, origin and direction. Every binary image operation checks it.
inline bool same_grid(const ImageGeometry& a, const ImageGeometry& b, double tol = 1e-4)
{
    if (a.size != b.size)
        return false;
    for (int i = 0; i < 3; ++i)
        if (std::abs(a.spacing[i] - b.spacing[i]) > tol || std::abs(a.origin[i] - b.origin[i]) > tol)
            return false;
    for (int i = 0; i < 9; ++i)
        if (std::abs(a.direction[i] - b.direction[i]) > tol)
            return false;
    return true;
}

//! A scalar image: geometry plus one value per voxel, x fastest.
template <class T>
struct Image3D : ImageGeometry {
    using value_type = T;
    BigVector<T> data; //!< voxel values; see big_buffer.h for the allocator

    Image3D() = default;
    //! An image on grid `g` filled with `value`.
    explicit Image3D(const ImageGeometry& g, T value = T{}) : ImageGeometry(g), data(g.voxel_count(), value) {}

    const ImageGeometry& geometry() const { return *this; }

    T& at(int i, int j, int k) { return data[index(i, j, k)]; }
    const T& at(int i, int j, int k) const { return data[index(i, j, k)]; }
};

//! Axial slice k of `image` as a 2-D image (size[2] == 1) that keeps its place in space: the
//! origin moves to the slice, spacing and direction stay. \throw InvalidInputError if k is
//! outside the image.
template <class T>
Image3D<T> axial_slice(const Image3D<T>& image, int k)
{
    if (k < 0 || k >= image.size[2])
        throw InvalidInputError("slice " + std::to_string(k) + " is outside the image (0.." +
                                std::to_string(image.size[2] - 1) + ")");
    ImageGeometry g = image.geometry();
    const Vec3 o = g.index_to_physical(0, 0, k);
    g.origin = {o.x, o.y, o.z};
    g.size[2] = 1;
    Image3D<T> out(g);
    const std::size_t n = static_cast<std::size_t>(g.size[0]) * static_cast<std::size_t>(g.size[1]);
    std::copy(image.data.begin() + static_cast<std::ptrdiff_t>(n * static_cast<std::size_t>(k)),
              image.data.begin() + static_cast<std::ptrdiff_t>(n * (static_cast<std::size_t>(k) + 1)), out.data.begin());
    return out;
}

//! A reordering of a grid's axes: axis a of the new grid is axis `from[a]` of the old one,
//! reversed where `flip[a]`. Every voxel keeps its physical position (reorder_axes).
struct AxisOrder {
    std::array<int, 3> from{0, 1, 2};
    std::array<bool, 3> flip{false, false, false};

    bool identity() const { return from == std::array<int, 3>{0, 1, 2} && !flip[0] && !flip[1] && !flip[2]; }
    //! Whether the axes only turn round, none changing place.
    bool flips_only() const { return from == std::array<int, 3>{0, 1, 2}; }
    //! The order that takes the new grid back to the old one.
    AxisOrder inverse() const
    {
        AxisOrder inv;
        for (std::size_t a = 0; a < 3; ++a) {
            inv.from[static_cast<std::size_t>(from[a])] = static_cast<int>(a);
            inv.flip[static_cast<std::size_t>(from[a])] = flip[a];
        }
        return inv;
    }
    //! The new grid's continuous index of a continuous index `old` of the old grid (`old_size`).
    Vec3 index_of(const Vec3& old, const std::array<int, 3>& old_size) const
    {
        Vec3 out;
        for (int a = 0; a < 3; ++a) {
            const int f = from[static_cast<std::size_t>(a)];
            out[a] = flip[static_cast<std::size_t>(a)] ? double(old_size[static_cast<std::size_t>(f)] - 1) - old[f] : old[f];
        }
        return out;
    }
};

//! The order that turns `g` onto the patient frame (LPS): axis a of the new grid runs along
//! patient axis a (x to the left, y to the back, z to the head), positively. Each old axis goes
//! to the patient axis it runs closest to (the assignment maximising the sum of |cosines|; ties
//! keep the old order), so an axial stack stays axial and a coronal or sagittal one becomes
//! axial. The identity for a grid already so stored.
inline AxisOrder patient_axis_order(const ImageGeometry& g)
{
    static constexpr std::array<std::array<int, 3>, 6> kPermutations{
        {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
    // p[a]: the patient axis old axis a goes to.
    std::array<int, 3> best = kPermutations[0];
    double best_sum = -1.0;
    for (const auto& p : kPermutations) {
        double sum = 0.0;
        for (int a = 0; a < 3; ++a)
            sum += std::abs(g.axis(a)[p[static_cast<std::size_t>(a)]]);
        if (sum > best_sum + 1e-9) {
            best_sum = sum;
            best = p;
        }
    }
    AxisOrder o;
    for (int a = 0; a < 3; ++a) {
        const auto to = static_cast<std::size_t>(best[static_cast<std::size_t>(a)]);
        o.from[to] = a;
        o.flip[to] = g.axis(a)[best[static_cast<std::size_t>(a)]] < 0.0;
    }
    return o;
}

//! `image` on its axes reordered by `order`, every voxel at the same physical position: the
//! spacing and direction columns follow their axes, a reversed axis's direction is negated and
//! the origin moves to the voxel that becomes (0, 0, 0). reorder_axes(reorder_axes(i, o),
//! o.inverse()) gives the image back (its origin to rounding). For code that reads an index
//! direction as an anatomical one (the liver pipeline reads +k as towards the head).
template <class T>
Image3D<T> reorder_axes(const Image3D<T>& image, const AxisOrder& order)
{
    const ImageGeometry& in = image.geometry();
    ImageGeometry g = in;
    std::array<int, 3> start{0, 0, 0};
    const std::array<std::ptrdiff_t, 3> in_stride{1, in.size[0], std::ptrdiff_t(in.size[0]) * in.size[1]};
    std::array<std::ptrdiff_t, 3> stride{};
    for (std::size_t a = 0; a < 3; ++a) {
        const auto f = static_cast<std::size_t>(order.from[a]);
        g.size[a] = in.size[f];
        g.spacing[a] = in.spacing[f];
        const double s = order.flip[a] ? -1.0 : 1.0;
        for (std::size_t r = 0; r < 3; ++r)
            g.direction[3 * r + a] = s * in.direction[3 * r + f];
        if (order.flip[a])
            start[f] = in.size[f] - 1;
        stride[a] = order.flip[a] ? -in_stride[f] : in_stride[f];
    }
    if (in.voxel_count() > 0) {
        const Vec3 o = in.index_to_physical(start[0], start[1], start[2]);
        g.origin = {o.x, o.y, o.z};
    }
    Image3D<T> out(g);
    if (out.data.empty())
        return out;
    const auto base = static_cast<std::ptrdiff_t>(in.index(start[0], start[1], start[2]));
    auto to = out.data.begin();
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j) {
            const std::ptrdiff_t row = base + k * stride[2] + j * stride[1];
            if (stride[0] == 1) {
                std::copy(image.data.begin() + row, image.data.begin() + row + g.size[0], to);
            } else {
                for (int i = 0; i < g.size[0]; ++i)
                    to[i] = image.data[static_cast<std::size_t>(row + i * stride[0])];
            }
            to += g.size[0];
        }
    return out;
}

//! `image` with the axes flagged in `turn` turned round, none changing place (reorder_axes).
template <class T>
Image3D<T> flip_axes(const Image3D<T>& image, std::array<bool, 3> turn)
{
    AxisOrder o;
    o.flip = turn;
    return reorder_axes(image, o);
}

//! `image` with its slices in reverse order (flip_axes of the third axis alone).
template <class T>
Image3D<T> reverse_slices(const Image3D<T>& image)
{
    return flip_axes(image, {false, false, true});
}

using ImageF = Image3D<float>;
using ImageI16 = Image3D<std::int16_t>;
using LabelImage3D = Image3D<std::uint8_t>;

} // namespace lobe::core
