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

//! `image` with the axes flagged in `turn` turned round, every voxel at the same physical
//! position: along a turned axis the voxel order reverses, the origin moves to the far end and
//! the axis's direction is negated. Turning the same axes twice gives the image back (its origin
//! to rounding). For code that reads an index direction as an anatomical one (the liver pipeline
//! reads +k as towards the head, and runs on a grid whose axes point along the patient frame).
template <class T>
Image3D<T> flip_axes(const Image3D<T>& image, std::array<bool, 3> turn)
{
    ImageGeometry g = image.geometry();
    const Vec3 far = g.index_to_physical(turn[0] ? g.size[0] - 1 : 0, turn[1] ? g.size[1] - 1 : 0,
                                         turn[2] ? g.size[2] - 1 : 0);
    if (g.size[0] > 0 && g.size[1] > 0 && g.size[2] > 0)
        g.origin = {far.x, far.y, far.z};
    for (std::size_t a = 0; a < 3; ++a)
        if (turn[a])
            for (std::size_t r = 0; r < 3; ++r)
                g.direction[3 * r + a] = -g.direction[3 * r + a];
    Image3D<T> out(g);
    const int nx = g.size[0], ny = g.size[1], nz = g.size[2];
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j) {
            const auto from = image.data.begin() + static_cast<std::ptrdiff_t>(image.index(0, turn[1] ? ny - 1 - j : j,
                                                                                           turn[2] ? nz - 1 - k : k));
            const auto to = out.data.begin() + static_cast<std::ptrdiff_t>(out.index(0, j, k));
            if (turn[0])
                std::reverse_copy(from, from + nx, to);
            else
                std::copy(from, from + nx, to);
        }
    return out;
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
