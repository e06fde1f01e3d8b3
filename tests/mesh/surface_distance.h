#pragma once
// Two-sided Hausdorff distance between a tet mesh's boundary and the label surface (the
// boundary of the union of the label's voxel boxes), for the meshing tests.

#include "lobe/core/geometry.h"
#include "lobe/core/image3d.h"
#include "lobe/core/tet_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <vector>

namespace lobe::test {

//! The faces of `m` with a tet on one side only (the outer boundary).
inline std::vector<std::array<core::Vec3, 3>> boundary_triangles(const core::TetMesh& m)
{
    std::map<std::array<std::int32_t, 3>, int> count;
    const int f[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    for (const auto& q : m.tets)
        for (const auto& i : f) {
            std::array<std::int32_t, 3> k{q[static_cast<std::size_t>(i[0])], q[static_cast<std::size_t>(i[1])],
                                          q[static_cast<std::size_t>(i[2])]};
            std::sort(k.begin(), k.end());
            ++count[k];
        }
    std::vector<std::array<core::Vec3, 3>> out;
    for (const auto& [k, n] : count)
        if (n == 1)
            out.push_back({m.vertices[static_cast<std::size_t>(k[0])], m.vertices[static_cast<std::size_t>(k[1])],
                           m.vertices[static_cast<std::size_t>(k[2])]});
    return out;
}

struct HausdorffResult {
    double mesh_to_labels = 0; //!< max over the mesh boundary of the distance to the label surface [mm]
    double labels_to_mesh = 0; //!< max over the label surface of the distance to the mesh boundary [mm]
    double max() const { return std::max(mesh_to_labels, labels_to_mesh); }
};

//! Hausdorff distance between the boundary of `m` and the surface of the voxels of `img` with a
//! non-zero label, both sampled (every triangle at its vertices, edge midpoints and centroid;
//! every voxel face on a 4 x 4 grid of points and its corners), each sample's distance exact.
//! Axis-aligned grids (identity direction) only. Distances beyond `limit` mm are reported as
//! `limit`: the tests need to know that they stay below a voxel, not how far beyond.
inline HausdorffResult hausdorff_to_labels(const core::TetMesh& m, const core::LabelImage3D& img, double limit)
{
    using core::Vec3;
    const auto& sp = img.spacing;
    auto inside = [&](int i, int j, int k) { return img.contains(i, j, k) && img.at(i, j, k) != 0; };
    // Mesh -> label surface: a sample inside the voxels is at the distance of the nearest box of
    // an outside voxel, and conversely (the surface is the common boundary of the two sets).
    const int reach[3] = {static_cast<int>(std::ceil(limit / sp[0])) + 1, static_cast<int>(std::ceil(limit / sp[1])) + 1,
                          static_cast<int>(std::ceil(limit / sp[2])) + 1};
    auto to_labels = [&](const Vec3& p) {
        const Vec3 x = img.physical_to_index(p);
        const int ci = static_cast<int>(std::lround(x.x)), cj = static_cast<int>(std::lround(x.y)),
                  ck = static_cast<int>(std::lround(x.z));
        const bool in = inside(ci, cj, ck);
        double best = limit;
        for (int k = ck - reach[2]; k <= ck + reach[2]; ++k)
            for (int j = cj - reach[1]; j <= cj + reach[1]; ++j)
                for (int i = ci - reach[0]; i <= ci + reach[0]; ++i) {
                    if (inside(i, j, k) == in)
                        continue;
                    const Vec3 c = img.index_to_physical(i, j, k);
                    double d2 = 0;
                    for (int a = 0; a < 3; ++a) {
                        const double e = std::max(std::abs(p[a] - c[a]) - sp[static_cast<std::size_t>(a)] / 2, 0.0);
                        d2 += e * e;
                    }
                    best = std::min(best, std::sqrt(d2));
                }
        return best;
    };
    HausdorffResult r;
    const auto tris = boundary_triangles(m);
    for (const auto& t : tris) {
        const Vec3 samples[7] = {t[0], t[1], t[2], (t[0] + t[1]) / 2, (t[1] + t[2]) / 2, (t[0] + t[2]) / 2,
                                 (t[0] + t[1] + t[2]) / 3};
        for (const auto& s : samples)
            r.mesh_to_labels = std::max(r.mesh_to_labels, to_labels(s));
    }
    // Label surface -> mesh: triangles bucketed on a grid of `limit` cells (each in every cell
    // its box, grown by `limit`, overlaps), so a sample needs only its own cell.
    Vec3 lo{1e300, 1e300, 1e300};
    for (const auto& t : tris)
        for (const auto& v : t)
            for (int a = 0; a < 3; ++a)
                lo[a] = std::min(lo[a], v[a] - 2 * limit);
    auto cell = [&](const Vec3& p) {
        return std::array<long, 3>{static_cast<long>(std::floor((p.x - lo.x) / limit)),
                                   static_cast<long>(std::floor((p.y - lo.y) / limit)),
                                   static_cast<long>(std::floor((p.z - lo.z) / limit))};
    };
    std::map<std::array<long, 3>, std::vector<std::size_t>> buckets;
    for (std::size_t n = 0; n < tris.size(); ++n) {
        Vec3 a{1e300, 1e300, 1e300}, b{-1e300, -1e300, -1e300};
        for (const auto& v : tris[n])
            for (int ax = 0; ax < 3; ++ax) {
                a[ax] = std::min(a[ax], v[ax] - limit);
                b[ax] = std::max(b[ax], v[ax] + limit);
            }
        const auto ca = cell(a), cb = cell(b);
        for (long i = ca[0]; i <= cb[0]; ++i)
            for (long j = ca[1]; j <= cb[1]; ++j)
                for (long k = ca[2]; k <= cb[2]; ++k)
                    buckets[{i, j, k}].push_back(n);
    }
    auto to_mesh = [&](const Vec3& p) {
        double best = limit;
        const auto it = buckets.find(cell(p));
        if (it != buckets.end())
            for (auto n : it->second)
                best = std::min(best, core::distance(p, core::closest_on_triangle(p, tris[n][0], tris[n][1], tris[n][2])));
        return best;
    };
    const int nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < img.size[1]; ++j)
            for (int i = 0; i < img.size[0]; ++i) {
                if (!inside(i, j, k))
                    continue;
                for (const auto& d : nb) {
                    if (inside(i + d[0], j + d[1], k + d[2]))
                        continue;
                    // The face between the voxel and its outside neighbour, sampled in index space.
                    const int axis = d[0] != 0 ? 0 : d[1] != 0 ? 1 : 2;
                    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
                    for (int a = 0; a <= 4; ++a)
                        for (int b = 0; b <= 4; ++b) {
                            Vec3 x{double(i), double(j), double(k)};
                            x[axis] += 0.5 * (d[0] + d[1] + d[2]);
                            x[u] += a / 4.0 - 0.5;
                            x[w] += b / 4.0 - 0.5;
                            r.labels_to_mesh = std::max(r.labels_to_mesh, to_mesh(img.index_to_physical(x)));
                        }
                }
            }
    return r;
}

} // namespace lobe::test
